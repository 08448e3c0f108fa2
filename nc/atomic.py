"""Write files atomically: a temporary file beside the target, then a rename.

A run that fails half-way leaves the previous file (or none) in place, never
a half-written NC program.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from typing import IO

__all__ = ["atomic_write", "atomic_path"]


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[str]:
    """A temporary file name beside ``path``; renamed onto it on success.

    For writers that take a file name rather than a file object (pyuff,
    savefig to a path). The temporary file exists, empty, when the block
    starts; on any exception it is removed and ``path`` is left as it was.
    """
    path = os.fspath(path)
    directory = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(directory):
        raise FileNotFoundError(f"{path}: directory {directory} does not exist")
    fd, tmp = tempfile.mkstemp(prefix="." + os.path.basename(path) + ".", suffix=".tmp",
                               dir=directory)
    os.close(fd)
    try:
        yield tmp
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


@contextlib.contextmanager
def atomic_write(path: str | os.PathLike, mode: str = "w", *,
                 encoding: str | None = "utf-8", newline: str | None = "\n") -> Iterator[IO]:
    """Open a temporary file for writing; rename it onto ``path`` on success.

    Parameters
    ----------
    path : path-like
        The file to (re)place. Its directory must exist.
    mode : str
        ``"w"`` (text) or ``"wb"`` (bytes).
    encoding, newline : str or None
        As for :func:`open`, text mode only.

    Notes
    -----
    The data are flushed and fsynced before the rename, and the rename is
    atomic on POSIX file systems. On any exception the temporary file is
    removed and ``path`` is left as it was.
    """
    with atomic_path(path) as tmp:
        if "b" in mode:
            fh = open(tmp, mode)
        else:
            fh = open(tmp, mode, encoding=encoding, newline=newline)
        with fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
