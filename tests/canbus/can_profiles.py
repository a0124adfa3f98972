"""Desk profiles with a `can:` section for the CAN tests, and where their errors point."""

from __future__ import annotations

import re

import pytest

from hapticdesk.canbus.config_reader import can_config
from hapticdesk.errors import ConfigError

HEAD = """name: t
sample_rate_hz: 1000
sensors:
  - {name: fl, position: [-0.3, -0.2, 0]}
  - {name: fr, position: [0.3, -0.2, 0]}
  - {name: bl, position: [-0.3, 0.2, 0]}
  - {name: br, position: [0.3, 0.2, 0]}
"""
SIGNALS = """    {n}: {{fx: {N}_FORCE.Fx, fy: {N}_FORCE.Fy, fz: {N}_FORCE.Fz,
         mx: {N}_MOMENT.Mx, my: {N}_MOMENT.My, mz: {N}_MOMENT.Mz,
         counter: [{N}_FORCE.Seq, {N}_MOMENT.Seq]}}
"""


def full_can(extra: str = "", skip: str = "") -> str:
    sensors = "".join(
        SIGNALS.format(n=n, N=n.upper()) for n in ("fl", "fr", "bl", "br") if n != skip
    )
    return HEAD + f"can:\n  database: kitamura2017.dbc\n{extra}  sensors:\n" + sensors


def error_at(load, text: str) -> tuple[int, int, str]:
    profile = load(text)
    with pytest.raises(ConfigError) as info:
        can_config(profile)
    match = re.match(r".*desk\.yaml:(\d+):(\d+): (.*)", str(info.value), re.S)
    assert match, str(info.value)
    return int(match[1]), int(match[2]), match[3]


def line_of(text: str, needle: str) -> int:
    return next(i for i, line in enumerate(text.splitlines(), 1) if needle in line)
