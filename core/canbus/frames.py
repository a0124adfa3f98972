"""CAN frames as a struct of numpy arrays, the form every decoding step works on.

Live buses and log readers give one python-can ``Message`` at a time; they are turned into a
:class:`FrameArray` in chunks so that classification, counters and signals are computed on
whole arrays.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

EXTENDED = np.uint32(0x8000_0000)  # set on 29-bit identifiers, as SocketCAN's CAN_EFF_FLAG

# bits of FrameArray.flags
REMOTE = 1
ERROR = 2
SENT = 4  # sent by this host (a poll request), not received


@dataclass
class FrameArray:
    """``n`` frames: times, identifiers, lengths, the first 8 data bytes, flags."""

    t: np.ndarray  # (n,) float64 seconds; NaN where the log has no times
    ident: np.ndarray  # (n,) uint32 arbitration id, | EXTENDED for 29-bit ids
    dlc: np.ndarray  # (n,) uint8 data length in bytes (up to 64 for CAN FD)
    data: np.ndarray  # (n, 8) uint8, zero padded
    flags: np.ndarray  # (n,) uint8: REMOTE, ERROR, SENT

    def __len__(self) -> int:
        return len(self.t)

    @classmethod
    def empty(cls) -> FrameArray:
        return cls(
            np.zeros(0),
            np.zeros(0, np.uint32),
            np.zeros(0, np.uint8),
            np.zeros((0, 8), np.uint8),
            np.zeros(0, np.uint8),
        )

    @classmethod
    def build(
        cls,
        t: Any,
        ident: Any,
        data: Sequence[bytes],
        *,
        extended: Any = False,
        flags: Any = 0,
    ) -> FrameArray:
        """From plain values (``data`` a sequence of bytes objects)."""
        n = len(data)
        ident_arr = np.broadcast_to(np.asarray(ident, dtype=np.uint32), (n,)).copy()
        ident_arr[np.broadcast_to(np.asarray(extended, dtype=bool), (n,))] |= EXTENDED
        dlc = np.fromiter((len(d) for d in data), dtype=np.uint8, count=n)
        packed = b"".join(bytes(d[:8]).ljust(8, b"\0") for d in data)
        return cls(
            np.broadcast_to(np.asarray(t, dtype=np.float64), (n,)).copy(),
            ident_arr,
            dlc,
            np.frombuffer(packed, dtype=np.uint8).reshape(n, 8).copy(),
            np.broadcast_to(np.asarray(flags, dtype=np.uint8), (n,)).copy(),
        )

    @classmethod
    def from_messages(cls, messages: Sequence[Any], sent: bool = False) -> FrameArray:
        """From python-can ``Message`` objects (``sent``: all were sent by this host)."""
        n = len(messages)
        if n == 0:
            return cls.empty()
        t = np.fromiter((m.timestamp for m in messages), dtype=np.float64, count=n)
        ident = np.fromiter((m.arbitration_id for m in messages), dtype=np.uint32, count=n)
        ext = np.fromiter((m.is_extended_id for m in messages), dtype=bool, count=n)
        ident[ext] |= EXTENDED
        dlc = np.fromiter((len(m.data) for m in messages), dtype=np.uint8, count=n)
        packed = b"".join(bytes(m.data[:8]).ljust(8, b"\0") for m in messages)
        remote = np.fromiter((m.is_remote_frame for m in messages), dtype=bool, count=n)
        error = np.fromiter((m.is_error_frame for m in messages), dtype=bool, count=n)
        flags = remote * np.uint8(REMOTE) | error * np.uint8(ERROR)
        if sent:
            flags |= np.uint8(SENT)
        else:
            tx = np.fromiter((not m.is_rx for m in messages), dtype=bool, count=n)
            flags |= tx * np.uint8(SENT)
        return cls(
            t,
            ident,
            dlc,
            np.frombuffer(packed, np.uint8).reshape(n, 8).copy(),
            flags.astype(np.uint8),
        )

    def to_messages(self, channel: Any = None, t0: float = 0.0) -> list[Any]:
        """python-can ``Message`` objects (times shifted by ``t0``; no time becomes 0)."""
        import can  # lazily: only CAN paths need python-can

        out = []
        t = np.where(np.isnan(self.t), 0.0, self.t + t0).tolist()
        ident = self.ident.tolist()
        dlc = self.dlc.tolist()
        flags = self.flags.tolist()
        data = self.data.tobytes()
        for i in range(len(self)):
            n = min(dlc[i], 8)
            out.append(
                can.Message(
                    timestamp=t[i],
                    arbitration_id=ident[i] & 0x1FFF_FFFF,
                    is_extended_id=bool(ident[i] & 0x8000_0000),
                    data=data[8 * i : 8 * i + n] if not flags[i] & REMOTE else None,
                    dlc=n,
                    is_remote_frame=bool(flags[i] & REMOTE),
                    is_error_frame=bool(flags[i] & ERROR),
                    is_rx=not flags[i] & SENT,
                    channel=channel,
                )
            )
        return out

    def take(self, index: Any) -> FrameArray:
        """A subset (mask, index array or slice)."""
        return FrameArray(**{f.name: getattr(self, f.name)[index] for f in fields(self)})

    @classmethod
    def concat(cls, parts: Sequence[FrameArray]) -> FrameArray:
        parts = [p for p in parts if len(p)]
        if not parts:
            return cls.empty()
        if len(parts) == 1:
            return parts[0]
        return cls(
            **{f.name: np.concatenate([getattr(p, f.name) for p in parts]) for f in fields(cls)}
        )
