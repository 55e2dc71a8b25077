"""Test-only observer plugins, importable by worker processes (``tests.plugins.X``)."""
