"""The desk's sensors from the contact stream: throttled, occupancy at once, resting load."""

from __future__ import annotations

from hapticdesk.plugins.mqtt.sensors import OCCUPANCY_HOLD_S, RATE_HZ, DeskState, SensorPublisher
from hapticdesk.runtime.observe import ContactSummary


def summary(t: float, force: float = 0.0, zero: float | None = 134.4) -> ContactSummary:
    touching = force > 1.0
    return ContactSummary(t, touching, force, 0.1 if touching else None, -0.05, zero)


def test_sensor_updates_are_throttled_but_occupancy_changes_go_at_once():
    sent: list[dict] = []
    sink = SensorPublisher(DeskState(), sent.append)
    blocks_per_s = 50
    for k in range(10 * blocks_per_s):  # 10 s of 20 ms blocks, a touch from 4.0 s to 4.5 s
        t = k / blocks_per_s
        sink(summary(t, 8.0 if 4.0 <= t < 4.5 else 0.0))
    assert len(sent) <= 10 * RATE_HZ + 2
    occupied = [s for s in sent if s["occupancy"]]
    assert occupied and occupied[0]["force_n"] == 8.0  # sent at the first touching block
    assert occupied[0]["x"] == 0.1 and occupied[0]["y"] == -0.05
    # the desk stays "in use" for a while after the touch, then frees at once
    last_touch = 4.48
    freed = None
    for k in range(int(OCCUPANCY_HOLD_S + 5) * blocks_per_s):
        t = 10.0 + k / blocks_per_s
        sink(summary(t))
        if not sent[-1]["occupancy"]:
            freed = t
            break
    assert freed is not None
    assert abs(freed - (last_touch + OCCUPANCY_HOLD_S)) <= 1.0 / blocks_per_s + 1e-9


def test_the_resting_load_is_what_the_zero_absorbed_since_the_tare():
    sent: list[dict] = []
    sink = SensorPublisher(DeskState(), sent.append)
    sink(summary(0.0, zero=None))  # before the tare: nothing to say about it
    assert sent[-1]["resting_load_n"] == 0.0
    sink(summary(1.0, zero=134.4))
    sink(summary(2.0, zero=154.0))  # a 2 kg laptop put down and absorbed into the zero
    assert sent[-1]["resting_load_n"] == 19.6
