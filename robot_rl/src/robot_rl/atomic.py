"""Crash-safe file writing (a temp file in the target's directory, fsync, rename over) and the locks that keep
another process from writing a folder at the same time."""
from __future__ import annotations

import contextlib
import fcntl
import json
import os
import secrets
from collections.abc import Iterator
from pathlib import Path
from typing import Any

StrPath = str | os.PathLike

_held_locks: dict[Path, int] = {}  # lock file -> the descriptor whose flock this process holds for its life


def _temp_name(path: Path) -> Path:
    return path.with_name(f".{path.name}.{os.getpid()}.{secrets.token_hex(4)}.tmp")


def _fsync_dir(directory: Path) -> None:
    fd = os.open(directory, os.O_RDONLY | os.O_DIRECTORY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def write_bytes_atomic(path: StrPath, data: bytes) -> None:
    """Replace `path` with `data` so readers see either the old or the new content, never a mix."""
    path = Path(path)
    tmp = _temp_name(path)
    # os.open with 0o666 (not mkstemp's 0o600) so the final file honours the umask.
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    _fsync_dir(path.parent)


def write_text_atomic(path: StrPath, text: str) -> None:
    """Atomically replace `path` with `text` (UTF-8)."""
    write_bytes_atomic(path, text.encode("utf-8"))


def write_json_atomic(path: StrPath, obj: Any) -> None:
    """Atomically write `obj` as JSON; NaN/inf raise ValueError (strict JSON only)."""
    try:
        text = json.dumps(obj, indent=None, sort_keys=True, allow_nan=False)
    except ValueError as e:
        raise ValueError(f"{path}: {e}") from e
    write_text_atomic(path, text + "\n")


def symlink_atomic(target: StrPath, link_path: StrPath) -> None:
    """Point the symlink `link_path` at `target`, replacing any existing link atomically."""
    link_path = Path(link_path)
    tmp = _temp_name(link_path)
    os.symlink(target, tmp)
    try:
        os.replace(tmp, link_path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    _fsync_dir(link_path.parent)


def hold_lock(path: Path) -> bool:
    """Hold an exclusive flock on the file `path` (made if missing) for the rest of this process's life; the kernel
    drops it when the process ends, however it ends. True if this process holds it (now, or already); False if
    another process does."""
    path = path.resolve()
    if path in _held_locks:
        return True
    fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        os.close(fd)
        return False
    _held_locks[path] = fd
    return True


@contextlib.contextmanager
def lock_while(path: Path, mode: int = 0o644) -> Iterator[bool]:
    """An exclusive flock on the file `path` (made with `mode` if missing) while the block runs: yields True if
    this process got it, False if another process holds it. Not inherited by children (PEP 446, O_CLOEXEC)."""
    fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, mode)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            yield False
            return
        yield True
    finally:
        os.close(fd)
