"""Every desk's gestures in one stream, the load split among several consumers.

    python examples/fleet/fleet_consumer.py --broker mqtt://localhost:1883 --group fleet \\
        --topic 'hapticdesk/+/+/+/event'

Subscribes to ``$share/<group>/<topic>``: the broker hands each message to ONE consumer of
the group, so starting a second copy of this script with the same ``--group`` halves the work
of each, and a consumer that stops leaves the rest to the others. Prints one JSON line per
event: ``{"desk": <the topic's prefix>, "event": {...}}``; ``--count N`` stops after N events
(for tests), ``--client-id`` names the consumer. Needs only paho-mqtt.
"""

from __future__ import annotations

import argparse
import json
import sys
import threading
import urllib.parse
from typing import Any

import paho.mqtt.client as mqtt
from paho.mqtt.packettypes import PacketTypes
from paho.mqtt.properties import Properties


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--broker", default="mqtt://localhost:1883")
    parser.add_argument("--group", default="hapticdesk-fleet", help="the shared group's name")
    parser.add_argument(
        "--topic",
        default="hapticdesk/+/+/+/event",
        help="the desks' event topics: hapticdesk/+/event for plain prefixes, "
        "hapticdesk/+/+/+/event for <site>/<floor>/<desk>",
    )
    parser.add_argument("--client-id", default="")
    parser.add_argument("--count", type=int, default=0, help="stop after this many events")
    args = parser.parse_args(argv)
    url = urllib.parse.urlsplit(args.broker)
    if url.scheme not in ("mqtt", "mqtts") or not url.hostname:
        parser.error(f"--broker must be mqtt://host[:port] or mqtts://host[:port]: {args.broker}")
    if any(c in args.group for c in "/+#"):
        parser.error("--group must not hold /, + or #")

    done = threading.Event()
    seen = 0

    def on_connect(client: Any, userdata: Any, flags: Any, reason: Any, props: Any) -> None:
        if reason.is_failure:
            print(f"the broker refused: {reason}", file=sys.stderr)
            done.set()
            return
        client.subscribe(f"$share/{args.group}/{args.topic}", qos=1)

    def on_subscribe(client: Any, userdata: Any, mid: Any, reasons: Any, props: Any) -> None:
        print(f"subscribed to $share/{args.group}/{args.topic}", file=sys.stderr, flush=True)

    def on_message(client: Any, userdata: Any, message: Any) -> None:
        nonlocal seen
        try:
            event = json.loads(message.payload)
        except (ValueError, UnicodeDecodeError):
            print(f"not JSON on {message.topic}; skipped", file=sys.stderr)
            return
        desk = message.topic.rsplit("/", 1)[0]
        print(json.dumps({"desk": desk, "event": event}), flush=True)
        seen += 1
        if args.count and seen >= args.count:
            done.set()

    client = mqtt.Client(
        mqtt.CallbackAPIVersion.VERSION2, client_id=args.client_id, protocol=mqtt.MQTTv5
    )
    client.on_connect, client.on_subscribe, client.on_message = (
        on_connect,
        on_subscribe,
        on_message,
    )
    if url.username:
        client.username_pw_set(url.username, None)
    if url.scheme == "mqtts":
        client.tls_set()
    session = Properties(PacketTypes.CONNECT)
    session.SessionExpiryInterval = 0  # a consumer that is gone takes no share of the load
    client.connect(url.hostname, url.port or 1883, 60, clean_start=True, properties=session)
    client.loop_start()
    try:
        done.wait()
    except KeyboardInterrupt:
        pass
    finally:
        client.disconnect()
        client.loop_stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())
