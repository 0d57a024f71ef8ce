"""``python -m isochor``: the same as the ``isochor`` command."""

from isochor.app.cli.main import entry

entry()
