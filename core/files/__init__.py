"""What comes from files: desk profiles, recordings, stroke files, and YAML with positions.

Every reader here reports bad input as :class:`~hapticdesk.errors.ConfigError` naming
``file:line:column`` (or ``file:row``) and what was expected.
"""
