"""The session's server of every lab model (see serve_tools)."""

from serve_tools import server  # noqa: F401
