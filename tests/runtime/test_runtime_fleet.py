"""The fleet benchmark, small: desks (each its own MqttLink) on a floor mosquitto bridged to a
building mosquitto, where shared-subscription consumers count every event."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import pytest

# the benchmark's worker processes are spawned: they import it by name, so it must be on the
# path that multiprocessing hands to them (it passes the parent's sys.path)
SCRIPTS = Path(__file__).resolve().parents[2] / "scripts"
if str(SCRIPTS) not in sys.path:
    sys.path.insert(0, str(SCRIPTS))

import fleet_bench  # noqa: E402


def test_three_desks_bridged_at_qos_2_lose_nothing_and_double_nothing(mosquitto_available, capsys):
    status = fleet_bench.main(
        [
            "--desks", "3",
            "--setups", "bridged",
            "--qos", "2",
            "--duration", "3",
            "--interval", "0.1", "0.3",
            "--consumers", "2",
            "--workers", "2",
            "--json",
        ]
    )  # fmt: skip
    rows = json.loads(capsys.readouterr().out)
    assert len(rows) == 1
    row = rows[0]
    assert (row["setup"], row["qos"], row["desks"]) == ("bridged", 2, 3)
    assert row["messages"] >= 3 * 3 / 0.3 * 0.5  # taps really went out (about 20 expected)
    assert row["lost"] == 0
    assert row["doubled"] == 0
    assert row["delivered"] == row["messages"]
    for key in ("p50_ms", "p95_ms", "max_ms"):
        assert math.isfinite(row[key]) and 0 <= row[key] < 5000, (key, row[key])
    assert row["p50_ms"] <= row["p95_ms"] <= row["max_ms"]
    assert status == 0


def test_a_desk_whose_events_never_arrive_counts_as_lost(mosquitto_available, monkeypatch):
    """The counting can fail: consumers that drop every other event report them lost."""
    original = fleet_bench.Consumers._on_message_for

    def dropping(self, k):
        handler = original(self, k)
        seen = []

        def on_message(client, userdata, message):
            seen.append(1)
            if len(seen) % 2:
                handler(client, userdata, message)

        return on_message

    monkeypatch.setattr(fleet_bench.Consumers, "_on_message_for", dropping)
    row = fleet_bench.run_once(
        "direct", 2, 1, duration=2, interval=(0.1, 0.2), consumers=1, workers=1, drain_s=1
    )
    assert row.messages >= 10
    assert row.lost == row.messages - row.delivered > 0
    assert row.doubled == 0


def test_bad_arguments_are_refused(capsys):
    with pytest.raises(SystemExit) as exit_info:
        fleet_bench.main(["--interval", "2", "1"])
    assert exit_info.value.code == 2
    assert "--interval" in capsys.readouterr().err
