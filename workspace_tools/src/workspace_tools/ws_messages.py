"""How ./ws speaks: its log lines ("[ws] ...") and the error that ends a command with one line saying why."""
from __future__ import annotations

import sys


class WsError(Exception):
    """A command that cannot go on; str() is the one line ./ws prints ("[ws] error: ...") before exiting 1."""


def log(message: str) -> None:
    print(f"[ws] {message}", file=sys.stderr, flush=True)
