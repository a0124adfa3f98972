"""``hapticdesk demo``: the whole path on a simulated desk, with real MQTT, in under a minute.

The paper's desk (simulated) plays examples/scenes/demo.yaml: tap the lamp button, slide the
dimmer, draw a circle, tap again. examples/layouts/demo.yaml turns the gestures into
Zigbee2MQTT commands; they travel through a broker (an embedded one on loopback unless
``--mqtt URL`` names yours) to a subscriber that plays the desk lamp and prints its state.

The MQTT plugin provides this command (``register_commands``): it needs the plugin's broker
and connection, and the core names no plugin.
"""

from __future__ import annotations

import argparse
import json
import sys
import threading
import time
from collections import Counter
from pathlib import Path
from typing import Any, NamedTuple, TextIO

import hapticdesk
from hapticdesk.errors import ConfigError
from hapticdesk.plugin_loading import load_registry
from hapticdesk.plugins.mqtt.settings import parse_broker_url
from hapticdesk.runtime.assembly import build_scene
from hapticdesk.runtime.lane import Lane
from hapticdesk.runtime.run_report import RunReport
from hapticdesk.runtime.service import Runtime

LAMP_TOPIC = "zigbee2mqtt/+/set"
ACTION_TOPIC = "hapticdesk/+/action"  # the desk's own gesture stream


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--mqtt", metavar="URL", help="use this broker instead of the embedded one")
    parser.add_argument(
        "--speed", type=float, default=1.0, help="1 real time (default), 0 as fast as possible"
    )
    parser.add_argument("--layout", help="another layout (default: examples/layouts/demo.yaml)")
    parser.add_argument("--scene", help="another scene (default: examples/scenes/demo.yaml)")


def examples_dir() -> Path:
    """The examples/ folder (the demo's layout and scene live there): the repository's, or
    the copy installed with the package."""
    package = Path(hapticdesk.__file__).resolve().parent
    repository = package.parent / "examples"
    if (repository / "layouts" / "demo.yaml").is_file():
        return repository
    return package / "examples"  # installed from a wheel (package data hapticdesk.examples)


class Lamp:
    """A stand-in for a Zigbee2MQTT light: subscribes to ``<device>/set`` and keeps its state.

    It speaks the Home Assistant JSON light schema Zigbee2MQTT uses: ``state`` ON, OFF or
    TOGGLE, ``brightness`` 0..254 (which also switches the light on).
    """

    def __init__(self, url: str, out: Any) -> None:
        import paho.mqtt.client as mqtt

        tls, self.host, self.port, username = parse_broker_url(url, "--mqtt")
        self.out = out
        self.state: dict[str, dict[str, Any]] = {}
        self.received = 0
        self._printed: dict[str, tuple[str, int]] = {}
        self._subscribed = threading.Event()
        self._lock = threading.Lock()
        self.client = mqtt.Client(
            mqtt.CallbackAPIVersion.VERSION2, client_id="hapticdesk-demo-lamp"
        )
        if username:
            self.client.username_pw_set(username)
        if tls:
            self.client.tls_set()
        self.client.on_connect = lambda c, u, f, reason, p: c.subscribe(
            [(LAMP_TOPIC, 2), (ACTION_TOPIC, 1)]
        )
        self.client.on_subscribe = lambda *a: self._subscribed.set()
        self.client.on_message = self._on_message

    def start(self, timeout: float = 10.0) -> Lamp:
        try:
            self.client.connect(self.host, self.port)
        except OSError as err:
            raise ConfigError(
                "--mqtt", f"cannot reach the broker at {self.host}:{self.port}: {err}"
            ) from None
        self.client.loop_start()
        if not self._subscribed.wait(timeout):
            raise ConfigError(
                "--mqtt", f"the broker at {self.host}:{self.port} did not accept a subscription"
            )
        return self

    def stop(self) -> None:
        self.client.disconnect()
        self.client.loop_stop()

    def _on_message(self, client: Any, userdata: Any, message: Any) -> None:
        if message.topic.startswith("hapticdesk/"):
            action = message.payload.decode("utf-8", "replace")
            if not action.endswith("_slide"):  # slide updates come every 50 ms
                print(f"gesture {action}", file=self.out, flush=True)
            return
        device = message.topic.split("/")[1]
        try:
            command = json.loads(message.payload)
        except ValueError:
            command = {}
        with self._lock:
            self.received += 1
            lamp = self.state.setdefault(device, {"state": "OFF", "brightness": 254})
            state = str(command.get("state", "")).upper()
            if state == "TOGGLE":
                lamp["state"] = "OFF" if lamp["state"] == "ON" else "ON"
            elif state in ("ON", "OFF"):
                lamp["state"] = state
            if isinstance(command.get("brightness"), int | float):
                lamp["brightness"] = max(0, min(254, int(command["brightness"])))
                lamp["state"] = "ON" if lamp["brightness"] > 0 else "OFF"
            self._show(device, lamp)

    def _show(self, device: str, lamp: dict[str, Any], force: bool = False) -> None:
        # a slide sends a command every 50 ms; print on/off changes and steps of 10 %
        last = self._printed.get(device)
        now = (lamp["state"], lamp["brightness"])
        if not force and last is not None and last[0] == now[0] and abs(last[1] - now[1]) < 25:
            return
        self._printed[device] = now
        percent = round(100 * lamp["brightness"] / 254)
        light = "ON " if lamp["state"] == "ON" else "OFF"
        print(f"  {device}: {light} brightness {percent:3d} %", file=self.out, flush=True)

    def final(self) -> None:
        with self._lock:
            for device, lamp in self.state.items():
                self._show(
                    device,
                    lamp,
                    force=self._printed.get(device) != (lamp["state"], lamp["brightness"]),
                )


class GestureCount:
    """The run's gestures as a person counts them (a dispatcher sink): a slide is one
    gesture, its updates are counted apart."""

    def __init__(self) -> None:
        self.gestures: Counter[str] = Counter()
        self.updates: Counter[str] = Counter()

    def __call__(self, event: Any) -> None:
        if event.phase == "update":
            self.updates[event.gesture] += 1
        elif event.phase in (None, "begin"):
            self.gestures[event.gesture] += 1

    def text(self) -> str:
        shown = [
            f"{n} {g}" + (f" ({self.updates[g]} updates)" if self.updates[g] else "")
            for g, n in self.gestures.most_common()
        ]
        return ", ".join(shown) or "none"


def run(args: argparse.Namespace) -> int:
    out = sys.stdout
    layout, scene_file = _demo_files(args)
    broker = None
    url = args.mqtt
    if url is None:
        from hapticdesk.plugins.mqtt.broker import EmbeddedBroker

        broker = EmbeddedBroker().start()
        url = broker.url
        print(f"embedded MQTT broker on {url} (MQTT 3.1.1)", file=out)
    # the embedded broker (amqtt) speaks MQTT 3.1.1 only, and the demo knows it: its desk
    # speaks 3.1.1 there from the start (no MQTT 5 asked, none refused); a broker given with
    # --mqtt is asked as the layout says
    mqtt_overrides = {"broker": url} if broker is None else {"broker": url, "protocol": "3.1.1"}
    lamp = None
    counted = GestureCount()
    try:
        lamp = Lamp(url, out).start()
        played = _play(layout, scene_file, mqtt_overrides, args.speed, counted, out)
        deadline = time.monotonic() + 5.0
        while lamp.received < played.commands_sent and time.monotonic() < deadline:
            time.sleep(0.02)
        lamp.final()
    finally:
        if lamp is not None:
            lamp.stop()
        if broker is not None:
            broker.stop()
    _summary(out, counted, played, lamp)
    return 0 if lamp.received == played.commands_sent and not played.report.error else 1


def _demo_files(args: argparse.Namespace) -> tuple[Path, Path]:
    """(the layout, the scene): the demo's own or those given; ConfigError when missing."""
    examples = examples_dir()
    layout = Path(args.layout) if args.layout else examples / "layouts" / "demo.yaml"
    scene_file = Path(args.scene) if args.scene else examples / "scenes" / "demo.yaml"
    for path, given in ((layout, args.layout), (scene_file, args.scene)):
        if given and not path.is_file():
            what = "not a regular file" if path.exists() else "no such file"
            raise ConfigError(str(path), what)
        if not path.is_file():
            raise ConfigError(
                str(path),
                "the demo's file is missing (examples/ not installed?); give --layout, --scene",
            )
    return layout, scene_file


class _Played(NamedTuple):
    """What the simulated desk did: the run's report and the commands its actions sent."""

    report: RunReport
    commands_sent: int


def _play(
    layout: Path,
    scene_file: Path,
    mqtt: dict[str, str],
    speed: float,
    counted: GestureCount,
    out: TextIO,
) -> _Played:
    """The scene played on the simulated desk, its actions publishing to ``mqtt["broker"]``
    (``mqtt``: the command line's overrides of the layout's ``mqtt:``)."""
    scene = build_scene(
        layout,
        f"sim:{scene_file}",
        load_registry(),
        speed=speed,
        overrides={"mqtt": mqtt},
    )
    scene.dispatcher.add_sink(Lane("the demo's count of gestures", counted))
    print(
        f"simulated desk `{scene.profile.name}` playing {scene_file.name} with layout "
        f"{layout.name}; the lamp listens on {LAMP_TOPIC}",
        file=out,
        flush=True,
    )
    report = Runtime(scene, status=sys.stderr if sys.stderr.isatty() else None).run()
    sent = sum(lane.stats.ok for route in scene.dispatcher.routes for lane in route.lanes)
    return _Played(report, sent)


def _summary(out: TextIO, counted: GestureCount, played: _Played, lamp: Lamp) -> None:
    print(f"gestures: {counted.text()}", file=out)
    print(f"commands: {played.commands_sent} sent, {lamp.received} received by the lamp", file=out)
    for line in played.report.notes:
        print(line, file=out)
    for device, state in lamp.state.items():
        percent = round(100 * state["brightness"] / 254)
        print(f"{device} ends {state['state']} at brightness {percent} %", file=out)
    if played.report.error:
        print(f"error: {played.report.error}", file=out)
