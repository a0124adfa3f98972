"""Drawn strokes: the unistroke recognizer, the built-in shapes and their templates, capture."""
