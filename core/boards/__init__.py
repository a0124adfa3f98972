"""Boards on a serial line: a microcontroller printing one sample a line (docs/serial.md).

The pieces, each one concept, in the order bytes flow through them:

- :mod:`~hapticdesk.boards.hello` — the board's hello line (channels, rate, stamp kind,
  per-channel time offsets, checksum) and the checksum itself;
- :mod:`~hapticdesk.boards.lines` — bytes into lines (bounded) and lines into samples, every
  bad line with its reason, vectorised over a read's lines;
- :mod:`~hapticdesk.boards.clock` — the board's stamps (sequence or µs) into sample times:
  wrap-around, lost samples, resets, gaps kept as gaps;
- :mod:`~hapticdesk.boards.alignment` — channels sampled at their own moments brought to the
  sample's time by interpolation, before the desk's map;
- :mod:`~hapticdesk.boards.settings` — the profile's ``serial:`` section and the source spec;
- :mod:`~hapticdesk.boards.stats` — what was read, dropped, lost, and the notices;
- :mod:`~hapticdesk.boards.decoder` — the above as one streaming stage (bytes in, blocks out);
- :mod:`~hapticdesk.boards.source` — the live source on a pyserial port (imported only when a
  run uses ``--source serial:``).
"""
