"""The simulator tests use the desks of tests/conftest.py."""
