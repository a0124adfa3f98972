"""The built-in gesture recognizers, one module each, registered through the plugin hooks."""
