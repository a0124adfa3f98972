"""Gestures: layouts of regions and bindings, and the recognizers that turn contacts into
gesture events (docs/reference: layout.md, gestures.md, files.md).

    from hapticdesk.gestures.layout_reader import load_layout
    from hapticdesk.gestures.engine import GestureEngine
    layout = load_layout("examples/layouts/demo.yaml")
    engine = GestureEngine(layout)              # builds only the recognizers it binds
    events = engine.feed(contact_block) + engine.flush(t_end)

Modules: layout (loading, validation, bindings), options (gesture settings), regions
(shapes on a surface), touch (one touch and its best position), recognizer (the interface),
engine, arbitration (one gesture per touch: which recognizer's gesture holds a touch); the
recognizers taps, long_press, pressure, swipe, slide, stroke; unistroke ($1/Protractor),
shapes (the built-in shapes), strokefile, capture. Nothing is imported here, so a scene
loads only what it uses.
"""
