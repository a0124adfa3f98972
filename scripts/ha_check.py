"""The desk as a real Home Assistant sees it: install Home Assistant, run a desk against it, and
fail on anything it does not accept.

    python scripts/ha_check.py [--mode entity|device|both] [--keep DIR]

1. Home Assistant (pinned below) is installed from the package registry into a venv of its own,
   kept between runs: ``$HAPTICDESK_HA_VENV``, else ``~/.cache/hapticdesk-ha/ha-<version>``
   (reused when its marker names the same pins). It needs Python 3.13.0 or later:
   ``$HAPTICDESK_HA_PYTHON``, else pyenv's 3.13.0, else ``python3.13`` on PATH. This install is
   the only download; Home Assistant itself runs with ``--skip-pip``.
2. mosquitto starts on a free loopback port; Home Assistant on another, with a fresh config.
   It is onboarded through its REST API (``/api/onboarding/users``, ``/auth/token``), a
   long-lived token is made over its WebSocket, and the MQTT config entry is added
   (``/api/config/config_entries/flow``).
3. For each discovery mode (``entity``, then ``device`` on the same Home Assistant: the move
   between them must keep every entity), ``hapticdesk run`` plays simulated scenes:

   - a start, then every gesture kind bound (tap, double tap, two long-press tiers, two press
     levels, slide, swipe, stroke, two-finger tap) twice in a row: every device trigger
     (``subscribe_trigger``) and the event entity (``state_changed``) must see each one as
     often as the desk sent it, the event with the gesture's data (x, y, value, seq);
   - a layout switch from the select (``select.select_option``), pressed the moment Home
     Assistant offers it (the desk ``online``): the new layout's triggers there, the old
     one's gone, the select showing it; a gesture of the new layout fires; a reload (the
     Reload button); the desk stopping: every entity unavailable, "connected" off;
   - a restart with a changed layout (a trigger removed, a tier moved): triggers follow, no
     conflict, and the moved tier fires.

   With both modes, a last run moves back from device-based to per-entity discovery: the same
   device, every entity under its id, the triggers listed and firing.

   Every WARNING or ERROR that Home Assistant's MQTT, template or device-automation code logs
   naming the desk fails the check.

Prints one line per check, then a summary (checks passed and failed, and seconds, per mode)
and ``N passed, N failed``; exit status 1 when any failed.
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import queue
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
import urllib.error
import urllib.parse
import urllib.request
from collections import Counter
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

HA_VERSION = "2025.4.4"  # the newest Home Assistant that runs on Python 3.13.0
FRONTEND_VERSION = "20250411.0"  # its frontend (homeassistant/package_constraints.txt)
PAHO_VERSION = "2.1.0"  # what its MQTT integration pins
PINS = [f"homeassistant=={HA_VERSION}", f"home-assistant-frontend=={FRONTEND_VERSION}",
        f"paho-mqtt=={PAHO_VERSION}"]  # fmt: skip
DESK = "hdcheck"  # a name that appears in no Home Assistant message but about the desk
REPO = Path(__file__).resolve().parent.parent
#: loggers whose warnings about the desk fail the check
WATCHED = re.compile(
    r"\[(homeassistant\.components\.(mqtt|device_automation|event|select|sensor|binary_sensor|"
    r"button)[^\]]*|homeassistant\.helpers\.template[^\]]*)\]"
)


# --- what is checked, and how it is said ----------------------------------------------------------


class Checks:
    def __init__(self) -> None:
        self.passed = 0
        self.failed: list[str] = []

    def check(self, ok: bool, what: str, detail: str = "") -> bool:
        print(f"{'ok  ' if ok else 'FAIL'} {what}" + (f": {detail}" if detail and not ok else ""))
        sys.stdout.flush()
        if ok:
            self.passed += 1
        else:
            self.failed.append(what)
        return ok


# --- installing Home Assistant --------------------------------------------------------------------


def ha_python() -> str:
    for candidate in (
        os.environ.get("HAPTICDESK_HA_PYTHON"),
        "/root/.pyenv/versions/3.13.0/bin/python3.13",
        shutil.which("python3.13"),
    ):
        if candidate and Path(candidate).exists():
            return candidate
    raise SystemExit("ha_check: Python 3.13 not found; set HAPTICDESK_HA_PYTHON")


def ha_venv() -> Path:
    default = Path.home() / ".cache" / "hapticdesk-ha" / f"ha-{HA_VERSION}"
    return Path(os.environ.get("HAPTICDESK_HA_VENV", default))


def install_ha(venv: Path) -> float:
    """Install the pinned Home Assistant into ``venv`` unless its marker says it is there; the
    seconds it took (0 when reused)."""
    marker = venv / "hapticdesk-pins.txt"
    python = venv / "bin" / "python"
    if marker.exists() and marker.read_text() == "\n".join(PINS) and python.exists():
        return 0.0
    started = time.monotonic()
    print(f"installing Home Assistant {HA_VERSION} into {venv} (about 5 minutes)")
    if venv.exists():
        shutil.rmtree(venv)
    subprocess.run([ha_python(), "-m", "venv", str(venv)], check=True)
    pip = [str(python), "-m", "pip", "install", "-q", "--disable-pip-version-check"]
    run_pip([*pip, PINS[0]])
    # Home Assistant's own constraints pin what its integrations' requirements pull in
    constraints = subprocess.run(
        [str(python), "-c", "import homeassistant, pathlib; print(pathlib.Path("
         "homeassistant.__file__).parent / 'package_constraints.txt')"],
        check=True, capture_output=True, text=True,
    ).stdout.strip()  # fmt: skip
    run_pip([*pip, "-c", constraints, *PINS[1:]])
    marker.write_text("\n".join(PINS))
    return time.monotonic() - started


def run_pip(command: list[str]) -> None:
    """pip, quiet unless it fails (then its last words, and the check stops)."""
    done = subprocess.run(command, capture_output=True, text=True)
    if done.returncode != 0:
        said = [line for line in done.stderr.splitlines() if "is ignored" not in line]
        print("\n".join(said[-40:]), file=sys.stderr)
        raise SystemExit(f"ha_check: installing Home Assistant failed: {' '.join(command[3:])}")


# --- processes ------------------------------------------------------------------------------------


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def wait_port(port: int, timeout: float, process: subprocess.Popen[Any]) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if process.poll() is not None:
            raise SystemExit(f"ha_check: {process.args[0]} ended with {process.returncode}")
        with socket.socket() as s:
            if s.connect_ex(("127.0.0.1", port)) == 0:
                return
        time.sleep(0.1)
    raise SystemExit(f"ha_check: nothing listens on port {port} after {timeout:g} s")


@contextmanager
def mosquitto(folder: Path) -> Iterator[int]:
    port = free_port()
    config = folder / "mosquitto.conf"
    config.write_text(f"listener {port} 127.0.0.1\nallow_anonymous true\n")
    program = shutil.which("mosquitto") or shutil.which("mosquitto", path="/usr/sbin")
    if program is None:
        raise SystemExit("ha_check: mosquitto is not installed (apt-get install mosquitto)")
    process = subprocess.Popen([program, "-c", str(config)], stderr=subprocess.DEVNULL)
    try:
        wait_port(port, 10, process)
        yield port
    finally:
        process.terminate()
        process.wait(10)


@contextmanager
def home_assistant(venv: Path, folder: Path) -> Iterator[tuple[int, Path, float]]:
    """Home Assistant on a free loopback port with a fresh config in ``folder``: (port, its
    log file, seconds it took to answer)."""
    port = free_port()
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "configuration.yaml").write_text(
        "homeassistant:\n  name: ha_check\n  latitude: 0\n  longitude: 0\n  elevation: 0\n"
        "  unit_system: metric\n  time_zone: UTC\n  country: DE\n  currency: EUR\n"
        f"http:\n  server_host: 127.0.0.1\n  server_port: {port}\n"
        "logger:\n  default: warning\n  logs:\n    homeassistant.components.mqtt: info\n"
    )
    log = folder / "home-assistant.log"
    started = time.monotonic()
    process = subprocess.Popen(
        [str(venv / "bin" / "python"), "-m", "homeassistant", "-c", str(folder), "--skip-pip",
         "--log-file", str(log)],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )  # fmt: skip
    try:
        wait_port(port, 120, process)
        while True:  # the port opens before the API answers
            try:
                urllib.request.urlopen(f"http://127.0.0.1:{port}/api/onboarding", timeout=5)
                break
            except (urllib.error.URLError, ConnectionError):
                time.sleep(0.2)
        yield port, log, time.monotonic() - started
    finally:
        process.send_signal(signal.SIGTERM)
        try:
            process.wait(30)
        except subprocess.TimeoutExpired:
            process.kill()


# --- talking to Home Assistant --------------------------------------------------------------------


def http(port: int, path: str, body: Any = None, token: str | None = None, form: bool = False):
    data = None
    headers = {}
    if body is not None:
        if form:
            data = urllib.parse.urlencode(body).encode()
            headers["Content-Type"] = "application/x-www-form-urlencoded"
        else:
            data = json.dumps(body).encode()
            headers["Content-Type"] = "application/json"
    if token:
        headers["Authorization"] = f"Bearer {token}"
    request = urllib.request.Request(f"http://127.0.0.1:{port}{path}", data, headers)
    with urllib.request.urlopen(request, timeout=30) as response:
        return json.loads(response.read() or b"null")


class HomeAssistantSocket:
    """Home Assistant's WebSocket API: commands by id, subscriptions' events in queues."""

    def __init__(self, port: int, token: str) -> None:
        from websockets.sync.client import connect

        self.ws = connect(f"ws://127.0.0.1:{port}/api/websocket", max_size=None)
        assert json.loads(self.ws.recv())["type"] == "auth_required"
        self.ws.send(json.dumps({"type": "auth", "access_token": token}))
        answer = json.loads(self.ws.recv())
        if answer["type"] != "auth_ok":
            raise SystemExit(f"ha_check: WebSocket login refused: {answer}")
        self._ids = itertools.count(1)
        self._results: dict[int, queue.Queue[Any]] = {}
        self.events: dict[int, queue.Queue[Any]] = {}
        self._lock = threading.Lock()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        try:
            for text in self.ws:
                message = json.loads(text)
                if message["type"] == "result":
                    self._results[message["id"]].put(message)
                elif message["type"] == "event" and message["id"] in self.events:
                    self.events[message["id"]].put(message["event"])
        except Exception:  # the connection closed at the end
            return

    def call(self, kind: str, **fields: Any) -> Any:
        with self._lock:
            number = next(self._ids)
            self._results[number] = queue.Queue()
            if kind.startswith("subscribe") or kind == "subscribe_trigger":
                self.events[number] = queue.Queue()
            self.ws.send(json.dumps({"id": number, "type": kind, **fields}))
        answer = self._results[number].get(timeout=30)
        if not answer["success"]:
            raise RuntimeError(f"{kind}: {answer.get('error')}")
        return answer["result"] if not kind.startswith("subscribe") else number

    def close(self) -> None:
        self.ws.close()


def onboard(port: int) -> str:
    """A user through onboarding, a token, then a long-lived token (over the WebSocket)."""
    client = f"http://127.0.0.1:{port}/"
    user = http(port, "/api/onboarding/users", {
        "client_id": client, "name": "Check", "username": "check",
        "password": os.urandom(12).hex(), "language": "en",
    })  # fmt: skip
    tokens = http(port, "/auth/token", {
        "grant_type": "authorization_code", "code": user["auth_code"], "client_id": client,
    }, form=True)  # fmt: skip
    socket_ = HomeAssistantSocket(port, tokens["access_token"])
    long_lived = socket_.call("auth/long_lived_access_token", client_name="ha_check", lifespan=1)
    socket_.close()
    return str(long_lived)


def add_mqtt(port: int, token: str, broker_port: int) -> dict[str, Any]:
    flow = http(port, "/api/config/config_entries/flow", {"handler": "mqtt"}, token)
    if flow.get("type") == "form" and flow.get("step_id") != "broker":
        flow = http(port, f"/api/config/config_entries/flow/{flow['flow_id']}",
                    {"next_step_id": "broker"}, token)  # fmt: skip
    return http(port, f"/api/config/config_entries/flow/{flow['flow_id']}",
                {"broker": "127.0.0.1", "port": broker_port}, token)  # fmt: skip


# --- the desk -------------------------------------------------------------------------------------

REGIONS = """regions:
  lamp: {rect: [-30, -20, -20, -10]}
  knob: {rect: [-5, -20, 5, -10]}
  pad: {rect: [20, -20, 30, -10]}
  dimmer: {rect: [-30, 16, 30, 24], axis: x}
  duo: {rect: [20, -2, 30, 8]}
"""
BINDINGS_A = """bindings:
  - {gesture: tap, region: lamp, do: {log: {}}}
  - {gesture: double_tap, region: lamp, do: {log: {}}}
  - {gesture: long_press, region: knob, hold_s: 0.8, do: {log: {}}}
  - {gesture: long_press, region: knob, hold_s: 1.6, do: {log: {}}}
  - {gesture: press, region: pad, levels: {light: 6, firm: 14}, do: {log: {}}}
  - {gesture: slide, region: dimmer, do: {log: {}}}
  - {gesture: swipe, direction: [up], do: {log: {}}}
  - {gesture: stroke, shape: [circle], do: {log: {}}}
  - {gesture: two_finger_tap, region: duo, do: {log: {}}}
"""
# layout `b` (switched to from the select): taps on the knob only
BINDINGS_B = """bindings:
  - {gesture: tap, region: knob, do: {log: {}}}
"""
# the restart's layout: the double tap gone, the second tier moved to 2.4 s
BINDINGS_C = BINDINGS_A.replace(
    "  - {gesture: double_tap, region: lamp, do: {log: {}}}\n", ""
).replace("hold_s: 1.6", "hold_s: 2.4")

SCENE_HEAD = """name: ha-check
desk: kitamura2017
units: cm
seed: 3
human: {tap_peak_n: [3, 5]}
"""
# every gesture kind twice in a row (sample time; the first 6 s let the check subscribe)
SCENE_ALL = (
    SCENE_HEAD
    + """quiet_s: 6.0
tail_s: 1.0
timeline:
  - press: {point: [25, 3], peak_n: 8, hold_s: 0.4, rise_n_per_s: 40, release_n_per_s: 80,
            start_s: 6.5}
  - tap: {point: [13, 11], start_s: 6.85, label: two fingers}
  - press: {point: [25, 3], peak_n: 8, hold_s: 0.4, rise_n_per_s: 40, release_n_per_s: 80,
            start_s: 8.5}
  - tap: {point: [13, 11], start_s: 8.85, label: two fingers}
  - tap: {point: [-25, -15], start_s: 11.0, label: tap}
  - tap: {point: [-25, -15], wait_s: 1.0, label: tap}
  - tap: {point: [-25, -15], label: double}
  - tap: {point: [-25, -15], wait_s: 0.15, label: double}
  - tap: {point: [-25, -15], label: double}
  - tap: {point: [-25, -15], wait_s: 0.15, label: double}
  - press: {point: [0, -15], hold_s: 0.6, peak_n: 8, label: tier 0.8}
  - press: {point: [0, -15], hold_s: 0.6, peak_n: 8, label: tier 0.8}
  - press: {point: [0, -15], hold_s: 2.2, peak_n: 8, label: tier 1.6}
  - press: {point: [0, -15], hold_s: 2.2, peak_n: 8, label: tier 1.6}
  - press: {point: [25, -15], hold_s: 0.3, peak_n: 9, label: light}
  - press: {point: [25, -15], hold_s: 0.3, peak_n: 9, label: light}
  - press: {point: [25, -15], hold_s: 0.3, peak_n: 20, label: firm}
  - press: {point: [25, -15], hold_s: 0.3, peak_n: 20, label: firm}
  - drag: {from: [-25, 20], to: [25, 20], label: slide}
  - drag: {from: [-25, 20], to: [25, 20], label: slide}
  - swipe: {from: [0, -8], to: [0, 8], repeat: 2, label: swipe}
  - stroke: {shape: circle, center: [-5, 0], size: 14, speed: 12, label: circle}
  - stroke: {shape: circle, center: [-5, 0], size: 14, speed: 12, label: circle}
"""
)
# quiet while the check switches the layout from the select, then knob taps (layout b), a
# quiet stretch for the reload, and knob taps again
SCENE_SWITCH = (
    SCENE_HEAD
    + """quiet_s: 2.0
tail_s: 1.0
timeline:
  - tap: {point: [0, -15], start_s: 14.0, label: knob}
  - tap: {point: [0, -15], wait_s: 1.0, label: knob}
  - tap: {point: [0, -15], start_s: 26.0, label: knob}
  - tap: {point: [0, -15], wait_s: 1.0, label: knob}
"""
)
SCENE_RESTART = (
    SCENE_HEAD
    + """quiet_s: 6.0
tail_s: 1.0
timeline:
  - press: {point: [0, -15], hold_s: 3.0, peak_n: 8, label: tier 2.4}
  - press: {point: [0, -15], hold_s: 3.0, peak_n: 8, label: tier 2.4}
"""
)


def write_desk(folder: Path, mode: str, bindings: str) -> Path:
    """The layout (with ``layouts: {b: ...}``) and its layout b, in ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    mqtt = f"mqtt: {{discovery: {mode}}}\n"
    (folder / "b.yaml").write_text(
        f"desk: kitamura2017\nunits: cm\ndesk_name: {DESK}\n{REGIONS}{BINDINGS_B}{mqtt}"
    )
    layout = folder / "layout.yaml"
    layout.write_text(
        f"desk: kitamura2017\nunits: cm\ndesk_name: {DESK}\nlayouts: {{b: b.yaml}}\n"
        f"{REGIONS}{bindings}{mqtt}"
    )
    return layout


class Desk:
    """``hapticdesk run`` in the background, its events in a JSONL file."""

    def __init__(self, layout: Path, scene: str, broker_port: int, speed: float) -> None:
        self.scene = layout.parent / "scene.yaml"
        self.scene.write_text(scene)
        self.events = layout.parent / "events.jsonl"
        self.out = layout.parent / "desk.log"
        self.process = subprocess.Popen(
            [sys.executable, "-m", "hapticdesk", "run", "--layout", str(layout),
             "--source", f"sim:{self.scene}", "--speed", str(speed), "--events",
             str(self.events), "--mqtt", f"mqtt://127.0.0.1:{broker_port}"],
            stdout=self.out.open("w"), stderr=subprocess.STDOUT, cwd=layout.parent,
        )  # fmt: skip

    def wait(self, timeout: float = 300) -> int:
        return self.process.wait(timeout)

    def sent(self) -> list[dict[str, Any]]:
        if not self.events.exists():
            return []
        return [json.loads(line) for line in self.events.read_text().splitlines() if line]


# --- Home Assistant's view of the desk ------------------------------------------------------------


def wait_for(what: Callable[[], Any], timeout: float, step: float = 0.25) -> Any:
    deadline = time.monotonic() + timeout
    while True:
        value = what()
        if value or time.monotonic() > deadline:
            return value
        time.sleep(step)


def device_id(ha: HomeAssistantSocket) -> str | None:
    for device in ha.call("config/device_registry/list"):
        if ["mqtt", f"hapticdesk_{DESK}"] in device["identifiers"]:
            return str(device["id"])
    return None


def triggers(ha: HomeAssistantSocket, device: str) -> dict[tuple[str, str], dict[str, Any]]:
    listed = ha.call("device_automation/trigger/list", device_id=device)
    return {(t["type"], t["subtype"]): t for t in listed if t.get("domain") == "mqtt"}


def entities(ha: HomeAssistantSocket, device: str) -> dict[str, str]:
    """unique_id -> entity_id of the desk's entities."""
    return {
        e["unique_id"]: e["entity_id"]
        for e in ha.call("config/entity_registry/list")
        if e.get("device_id") == device
    }


def listen(ha: HomeAssistantSocket, trigger: dict[str, Any]) -> int:
    """Subscribe to a device trigger as listed; the subscription's number (its events in
    ``ha.events``)."""
    return int(ha.call("subscribe_trigger", trigger={k: v for k, v in trigger.items()
                                                     if k != "metadata"}))  # fmt: skip


def states(ha: HomeAssistantSocket) -> dict[str, dict[str, Any]]:
    return {s["entity_id"]: s for s in ha.call("get_states")}


def drain(q: queue.Queue[Any]) -> list[Any]:
    out = []
    while True:
        try:
            out.append(q.get_nowait())
        except queue.Empty:
            return out


def expected_payloads(sent: list[dict[str, Any]], wanted: set[str]) -> Counter[str]:
    """How often each trigger payload should fire for what the desk sent (a trigger renders
    the event's action, with ``_<hold_s>s`` for a tier trigger)."""
    out: Counter[str] = Counter()
    for event in sent:
        action = event["action"] if "action" in event else None
        if action is None:
            continue
        for payload in (action, f"{action}_{event.get('hold_s')}s"):
            if payload in wanted:
                out[payload] += 1
    return out


def with_actions(sent: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The events file has no ``action``: the desk's own action string, as the plugin makes."""
    from hapticdesk.gestures.event import GestureEvent

    known = set(GestureEvent.__dataclass_fields__) - {"extra"}
    out = []
    for e in sent:
        event = GestureEvent(**{k: v for k, v in e.items() if k in known})
        out.append({**e, "action": event.action_name})
    return out


def warnings_about_desk(log: Path, start: int) -> tuple[list[str], int]:
    """WARNING/ERROR records of the watched loggers after byte ``start`` that name the desk
    (with their traceback lines); and where the log ends now."""
    text = log.read_text(errors="replace") if log.exists() else ""
    records = re.split(r"\n(?=\d{4}-\d\d-\d\d \d\d:\d\d:\d\d\.\d+ )", text[start:])
    bad = [
        r.strip()
        for r in records
        if re.match(r"\S+ \S+ (WARNING|ERROR|CRITICAL) ", r)
        and WATCHED.search(r.split("\n", 1)[0])
        and DESK in r
    ]
    return bad, len(text)


# --- the checks -----------------------------------------------------------------------------------


def gestures_phase(
    c: Checks, ha: HomeAssistantSocket, folder: Path, mode: str, broker: int, known: dict
) -> None:
    layout = write_desk(folder, mode, BINDINGS_A)
    desk = Desk(layout, SCENE_ALL, broker, speed=2.0)
    device = wait_for(lambda: device_id(ha), 20)
    if not c.check(bool(device), f"{mode}: the desk is a device in Home Assistant"):
        desk.process.kill()
        return
    want = set(discovery_payloads(layout))
    listed = wait_for(lambda: set(triggers(ha, device)) == want and triggers(ha, device), 20)
    c.check(bool(listed), f"{mode}: its {len(want)} device triggers are listed",
            f"missing {want - set(triggers(ha, device))}")  # fmt: skip
    subscriptions = {key: listen(ha, t) for key, t in (listed or {}).items()}
    ids = wait_for(lambda: entities(ha, device), 10)
    event_entity = ids.get(f"hapticdesk_{DESK}_gesture")
    events = ha.call("subscribe_events", event_type="state_changed")
    if mode == "device" and known:
        c.check(known.get("device") == device, "device: the same device after the migration",
                f"{known.get('device')} -> {device}")  # fmt: skip
        c.check(ids == known.get("entities"), "device: every entity kept its id after migration",
                f"{known.get('entities')} -> {ids}")  # fmt: skip
    known.update(device=device, entities=ids)
    code = desk.wait()
    c.check(code == 0, f"{mode}: the desk ran the scene", desk.out.read_text()[-400:])
    time.sleep(2.0)  # Home Assistant's last events
    sent = with_actions(desk.sent())
    fired: Counter[tuple[str, str]] = Counter()
    for key, number in subscriptions.items():
        fired[key] = len(drain(ha.events[number]))
    # what each trigger should have seen, from the discovery configs (payload per type/subtype)
    configs = discovery_payloads(layout)
    payloads = {key: cfg["payload"] for key, cfg in configs.items()}
    wanted = expected_payloads(sent, set(payloads.values()))
    for key, payload in sorted(payloads.items()):
        c.check(
            fired[key] == wanted[payload] and wanted[payload] >= 2,
            f"{mode}: trigger {key[1]} {key[0]} fired for each of its {wanted[payload]} gestures",
            f"fired {fired[key]}",
        )
    # each event once, by its seq (a state coming back from unavailable is an old event)
    changes = [
        e["data"]
        for e in drain(ha.events[events])
        if e["data"]["entity_id"] == event_entity
        and e["data"].get("new_state")
        and (e["data"].get("old_state") or {}).get("state") != "unavailable"
        and e["data"]["new_state"]["state"] not in ("unavailable", "unknown")
    ]
    by_seq = {ch["new_state"]["attributes"].get("seq"): ch for ch in changes}
    seen = Counter(ch["new_state"]["attributes"].get("event_type") for ch in by_seq.values())
    c.check(len(by_seq) == len(changes), f"{mode}: each event reached the entity once",
            f"{len(changes)} changes for {len(by_seq)} events")  # fmt: skip
    types = set(configs_event_types(layout))
    wanted_types = Counter(e["action"] for e in sent if e["action"] in types)
    c.check(seen == wanted_types, f"{mode}: the event entity saw every gesture, each repeat too",
            f"missing {wanted_types - seen}, extra {seen - wanted_types}")  # fmt: skip
    kinds = {a.split("_", 1)[1] for a in seen}
    c.check(all(n >= 2 for n in wanted_types.values()),
            f"{mode}: every event type came at least twice ({len(kinds)} kinds)")  # fmt: skip
    attrs = [ch["new_state"]["attributes"] for ch in changes if ch["new_state"]["attributes"]]
    slides = [a for a in attrs if a.get("gesture") == "slide"]
    c.check(
        bool(attrs)
        and all("x" in a and "y" in a and "seq" in a for a in attrs if "gesture" in a)
        and bool(slides)
        and all("value" in a for a in slides),
        f"{mode}: the event carries the gesture's data (x, y, value, seq)",
    )
    for number in [*subscriptions.values(), events]:
        ha.call("unsubscribe_events", subscription=number)


def discovery_payloads(layout: Path) -> dict[tuple[str, str], dict[str, Any]]:
    """(type, subtype) -> trigger config, as the plugin builds them for ``layout``."""
    return {
        (c.config["type"], c.config["subtype"]): c.config
        for c in desk_configs(layout)
        if c.config.get("automation_type") == "trigger"
    }


def configs_event_types(layout: Path) -> list[str]:
    for c in desk_configs(layout):
        if "event_types" in c.config:
            return list(c.config["event_types"])
    return []


def desk_configs(layout: Path) -> list[Any]:
    from hapticdesk.plugin_loading import load_registry
    from hapticdesk.plugins.mqtt import discovery_for
    from hapticdesk.plugins.mqtt.settings import settings_from_layout
    from hapticdesk.runtime.assembly import load_scene_layout

    loaded, profile = load_scene_layout(layout, load_registry(entry_points=False), None)

    class Context:
        desk_name = DESK

    context = Context()
    context.layout = loaded  # type: ignore[attr-defined]
    context.profile = profile  # type: ignore[attr-defined]
    settings = settings_from_layout(loaded.raw.get("mqtt"), desk=DESK)
    return discovery_for(context, settings)  # type: ignore[arg-type]


def switch_phase(c: Checks, ha: HomeAssistantSocket, folder: Path, mode: str, broker: int) -> None:
    layout = write_desk(folder, mode, BINDINGS_A)
    sub = shutil.which("mosquitto_sub") or "mosquitto_sub"
    watch = subprocess.Popen([sub, "-p", str(broker), "-t", "hapticdesk/#", "-v"],
                             stdout=(folder / "topics.log").open("w"))  # fmt: skip
    try:
        switch_and_reload(c, ha, layout, mode, broker)
    finally:
        watch.terminate()


def switch_and_reload(c: Checks, ha: HomeAssistantSocket, layout: Path, mode: str, broker: int):
    desk = Desk(layout, SCENE_SWITCH, broker, speed=1.0)
    device = wait_for(lambda: device_id(ha), 20)
    select = f"select.{DESK}_layout"
    # as a person would: the select is pressed the moment Home Assistant offers it (the desk
    # is `online`), whether or not the desk has begun to sense
    ok = wait_for(lambda: states(ha).get(select, {}).get("state") == "default", 15, step=0.05)
    c.check(bool(ok), f"{mode}: the select shows the running layout (default)",
            str(states(ha).get(select)))  # fmt: skip
    ha.call("call_service", domain="select", service="select_option",
            service_data={"option": "b"}, target={"entity_id": select})  # fmt: skip
    ok = wait_for(lambda: states(ha).get(select, {}).get("state") == "b", 10)
    c.check(bool(ok), f"{mode}: the select shows layout b after the switch")
    now = wait_for(lambda: set(triggers(ha, device)) == {("button_short_press", "knob")}, 10)
    c.check(bool(now), f"{mode}: after the switch only layout b's trigger is there",
            str(sorted(triggers(ha, device))))  # fmt: skip
    knob = triggers(ha, device).get(("button_short_press", "knob"))
    if knob is None:
        desk.process.kill()
        return
    number = listen(ha, knob)
    got = wait_for(lambda: ha.events[number].qsize() >= 2, 25)
    c.check(bool(got), f"{mode}: layout b's tap fires its trigger, twice in a row",
            f"{ha.events[number].qsize()}")  # fmt: skip
    drain(ha.events[number])
    ha.call("call_service", domain="button", service="press",
            target={"entity_id": f"button.{DESK}_reload_layout"})  # fmt: skip
    got = wait_for(lambda: ha.events[number].qsize() >= 2, 25)
    c.check(bool(got), f"{mode}: after a reload the trigger fires again",
            f"{ha.events[number].qsize()}")  # fmt: skip
    c.check(states(ha).get(select, {}).get("state") == "b", f"{mode}: the select still says b")
    ha.call("unsubscribe_events", subscription=number)
    code = desk.wait()
    c.check(code == 0, f"{mode}: the desk ran the switch scene", desk.out.read_text()[-400:])
    # every entity unavailable, but the connectivity sensor (the availability itself): off
    ids = entities(ha, device)
    connected = ids.get(f"hapticdesk_{DESK}_connectivity")
    wanted = {e: "off" if e == connected else "unavailable" for e in ids.values()}

    def stopped() -> bool:
        now = states(ha)
        return all(now.get(e, {}).get("state") == state for e, state in wanted.items())

    gone = wait_for(stopped, 10)
    detail = {e: states(ha).get(e, {}).get("state") for e in ids.values()}
    c.check(bool(gone) and connected is not None and len(ids) > 1,
            f"{mode}: the desk stopped: its {len(ids) - 1} entities unavailable, connected off",
            str(detail))  # fmt: skip


def restart_phase(c: Checks, ha: HomeAssistantSocket, folder: Path, mode: str, broker: int) -> None:
    layout = write_desk(folder, mode, BINDINGS_C)
    desk = Desk(layout, SCENE_RESTART, broker, speed=2.0)
    device = wait_for(lambda: device_id(ha), 20)
    wanted = set(discovery_payloads(layout))
    ok = wait_for(lambda: set(triggers(ha, device)) == wanted, 20)
    c.check(bool(ok), f"{mode}: after a restart with a changed layout the triggers follow it",
            f"missing {wanted - set(triggers(ha, device))}, "
            f"left {set(triggers(ha, device)) - wanted}")  # fmt: skip
    tier = triggers(ha, device).get(("button_long_press_2.4s", "knob"))
    if tier is None:
        desk.process.kill()
        return
    number = listen(ha, tier)
    desk.wait()
    got = wait_for(lambda: ha.events[number].qsize() >= 2, 10)
    c.check(bool(got), f"{mode}: the moved tier (2.4 s) fires, twice",
            f"{ha.events[number].qsize()}")  # fmt: skip
    ha.call("unsubscribe_events", subscription=number)


def back_phase(
    c: Checks, ha: HomeAssistantSocket, folder: Path, broker: int, known: dict[str, Any]
) -> None:
    """From device-based discovery back to one config each: the same device, every entity
    under its id, the triggers there and firing."""
    layout = write_desk(folder, "entity", BINDINGS_A)
    desk = Desk(layout, SCENE_RESTART, broker, speed=1.0)  # (the migration takes a while)
    device = wait_for(lambda: device_id(ha), 20)
    wanted = set(discovery_payloads(layout))
    listed = wait_for(lambda: set(triggers(ha, device)) == wanted and triggers(ha, device), 20)
    c.check(bool(listed), "device→entity: the triggers are listed",
            f"missing {wanted - set(triggers(ha, device))}")  # fmt: skip
    c.check(device == known.get("device"), "device→entity: the same device",
            f"{known.get('device')} -> {device}")  # fmt: skip
    ids = wait_for(lambda: entities(ha, device) == known.get("entities") and entities(ha, device),
                   10)  # fmt: skip
    c.check(bool(ids), "device→entity: every entity kept its id",
            f"{known.get('entities')} -> {entities(ha, device)}")  # fmt: skip
    tier = (listed or {}).get(("button_long_press_1.6s", "knob"))
    if tier is None:
        desk.process.kill()
        return
    number = listen(ha, tier)
    code = desk.wait()
    c.check(code == 0, "device→entity: the desk ran its scene", desk.out.read_text()[-400:])
    got = wait_for(lambda: ha.events[number].qsize() >= 2, 10)
    c.check(bool(got), "device→entity: the 1.6 s tier fires, twice",
            f"{ha.events[number].qsize()}")  # fmt: skip
    ha.call("unsubscribe_events", subscription=number)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--mode", choices=("entity", "device", "both"), default="both")
    parser.add_argument("--keep", type=Path, help="keep the run's files here")
    args = parser.parse_args(argv)
    c = Checks()
    began = time.monotonic()
    venv = ha_venv()
    installed = install_ha(venv)
    how = f"installed in {installed:.0f} s" if installed else "reused"
    print(f"Home Assistant {HA_VERSION} in {venv} ({how})")
    folder = Path(args.keep or tempfile.mkdtemp(prefix="ha_check-"))
    folder.mkdir(parents=True, exist_ok=True)
    modes = ["entity", "device"] if args.mode == "both" else [args.mode]
    with mosquitto(folder) as broker, home_assistant(venv, folder / "ha") as (port, log, start_s):
        print(f"Home Assistant answered in {start_s:.1f} s; mosquitto on port {broker}")
        token = onboard(port)
        entry = add_mqtt(port, token, broker)
        c.check(entry.get("type") == "create_entry", "the MQTT integration is set up", str(entry))
        ha = HomeAssistantSocket(port, token)
        at = 0
        known: dict[str, Any] = {}
        summary: list[tuple[str, int, int, float]] = []  # part, passed, failed, seconds

        @contextmanager
        def part(name: str) -> Iterator[None]:
            """The phases run under it, then the log's warnings; their counts and time."""
            nonlocal at
            t0, passed, failed = time.monotonic(), c.passed, len(c.failed)
            yield
            bad, at = warnings_about_desk(log, at)
            c.check(not bad, f"{name}: no warning or error about the desk in Home Assistant's log",
                    "\n" + "\n".join(bad[:20]))  # fmt: skip
            seconds = time.monotonic() - t0
            summary.append((name, c.passed - passed, len(c.failed) - failed, seconds))
            print(f"{name}: {seconds:.0f} s")

        for mode in modes:
            with part(mode):
                gestures_phase(c, ha, folder / f"{mode}-all", mode, broker, known)
                switch_phase(c, ha, folder / f"{mode}-switch", mode, broker)
                restart_phase(c, ha, folder / f"{mode}-restart", mode, broker)
        if modes == ["entity", "device"]:  # and back, keeping every entity
            with part("device→entity"):
                back_phase(c, ha, folder / "back", broker, known)
        ha.close()
    print(f"\nha_check summary (Home Assistant {HA_VERSION}, {how}, started in {start_s:.1f} s)")
    for name, passed, failed, seconds in summary:
        print(f"  {name:<14} {passed:3d} passed {failed:3d} failed {seconds:6.0f} s")
    print(f"  {'in all':<14} {c.passed:3d} passed {len(c.failed):3d} failed "
          f"{time.monotonic() - began:6.0f} s; files in {folder}")  # fmt: skip
    for what in c.failed:
        print(f"  FAILED: {what}")
    print(f"{c.passed} passed, {len(c.failed)} failed")
    if not args.keep and not c.failed:
        shutil.rmtree(folder, ignore_errors=True)
    return 1 if c.failed else 0


if __name__ == "__main__":
    sys.exit(main())
