"""A message the MQTT link publishes, and how a payload becomes its bytes."""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class Message:
    """One message to publish. ``command`` False marks availability and discovery messages."""

    topic: str
    payload: bytes
    qos: int
    retain: bool
    command: bool = True


def encode_payload(payload: Any) -> bytes:
    """Text as UTF-8, mappings and lists as JSON (never NaN), numbers as their text."""
    if isinstance(payload, bytes):
        return payload
    if isinstance(payload, str):
        return payload.encode("utf-8")
    if payload is None:
        return b""
    if isinstance(payload, bool | int | float):
        return json.dumps(payload, allow_nan=False).encode("utf-8")
    return json.dumps(payload, allow_nan=False, ensure_ascii=False).encode("utf-8")
