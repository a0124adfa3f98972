"""Force/torque sensors over CAN (python-can, cantools), imported only by desks that use it.

:mod:`~hapticdesk.canbus.config` the profile's ``can:`` section (read by
:mod:`~hapticdesk.canbus.config_reader`, with :mod:`~hapticdesk.canbus.config_sensors` and
:mod:`~hapticdesk.canbus.can_database`);
:mod:`~hapticdesk.canbus.frames` frames as numpy arrays;
:mod:`~hapticdesk.canbus.dbc_signals` database signals as vectorised bit extraction;
:mod:`~hapticdesk.canbus.ati_netcanoem` the ATI NETCANOEM protocol;
:mod:`~hapticdesk.canbus.decoding` frame kinds and sensor readings of a desk;
:mod:`~hapticdesk.canbus.assembler` frames into samples;
:mod:`~hapticdesk.canbus.source` the live CAN source (its bus named by
:mod:`~hapticdesk.canbus.bus_spec`, its ATI boards asked and polled by
:mod:`~hapticdesk.canbus.ati_bus`);
:mod:`~hapticdesk.canbus.logs` CAN logs, one module per format (read, replay, write);
:mod:`~hapticdesk.canbus.frame_encoder` a desk's samples as frames;
:mod:`~hapticdesk.canbus.emulator` those frames on a bus. See docs/can.md.
"""
