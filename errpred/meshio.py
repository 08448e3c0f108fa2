"""Reading mesh files (STL and whatever else trimesh reads): the one way in.

Every mesh the project reads from a file -- a scenario's stock and design, the
planner's stock, the simulation's -- goes through :func:`load_mesh`. Whatever
goes wrong (no file, an empty or corrupt file, no triangles, coordinates that
are not finite, a stock that is not closed) raises :class:`MeshFileError`, an
:class:`nc.errors.InputError` whose message names the file, so the command lines
end in one line with exit status 2 instead of a trimesh traceback.

trimesh reads a text (ASCII) STL only with ``charset_normalizer`` installed
(declared in ``pyproject.toml``); a missing dependency is not bad input and is
not turned into one here.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from nc.errors import InputError

from . import constants as K

__all__ = ["MeshFileError", "load_mesh", "check_closed"]


class MeshFileError(InputError):
    """A mesh file that cannot be used; the message names the file.

    Attributes
    ----------
    file : str
        The mesh file as given.
    """

    def __init__(self, file: str, message: str) -> None:
        self.file = file
        super().__init__(f"{file}: {message}")


def load_mesh(path: str | os.PathLike, *, what: str = "mesh", closed: bool = False) -> Any:
    """Read a triangle mesh from a file, checked.

    Parameters
    ----------
    path : path-like
        The mesh file (STL, binary or text; any format trimesh reads).
    what : str
        What the mesh is, for messages (``"stock mesh"``, ``"design mesh"``).
    closed : bool
        Also require a closed (watertight), consistently oriented mesh: material
        inside a stock is undefined otherwise.

    Returns
    -------
    trimesh.Trimesh

    Raises
    ------
    MeshFileError
        No such file, an empty or unreadable one, more than
        :data:`errpred.constants.MAX_MESH_FILE_BYTES`, no triangles, coordinates
        that are not finite, (``closed``) a mesh that is not closed, or a closed mesh
        whose triangles are not consistently oriented.
    """
    import trimesh

    p = os.fspath(path)
    if not os.path.isfile(p):
        raise MeshFileError(p, f"{what} file not found")
    size = os.path.getsize(p)
    if size == 0:
        raise MeshFileError(p, f"empty file; expected a {what} (STL)")
    if size > K.MAX_MESH_FILE_BYTES:
        raise MeshFileError(p, f"{size / 2**20:.0f} MiB; expected a {what} of at most "
                               f"{K.MAX_MESH_FILE_BYTES / 2**20:.0f} MiB "
                               f"(errpred.constants.MAX_MESH_FILE_BYTES)")
    try:
        # unprocessed first: processing drops triangles with NaN corners without a word
        mesh = trimesh.load(p, force="mesh", process=False)
    except ImportError:  # a missing dependency is not the file's fault
        raise
    except Exception as exc:  # trimesh raises many kinds for a corrupt file
        raise MeshFileError(p, f"cannot read the {what}: {type(exc).__name__}: "
                               f"{_first_line(exc)}") from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise MeshFileError(p, f"no triangles read; expected a {what} (STL)")
    if not np.isfinite(mesh.vertices).all():
        raise MeshFileError(p, f"the {what} has coordinates that are not finite numbers")
    mesh.process()  # merge the corners an STL repeats per triangle (trimesh's default)
    if closed or mesh.is_watertight:
        # a closed mesh has an inside (the stock's material, the design's part): its
        # triangles must agree on it, checked here rather than at its first inside test
        check_closed(mesh, p, what)
    return mesh


def check_closed(mesh: Any, name: str, what: str = "stock mesh") -> None:
    """Raise :class:`MeshFileError` unless ``mesh`` is closed and consistently oriented."""
    if not mesh.is_watertight:
        raise MeshFileError(name, f"the {what} is not watertight (closed): material inside "
                                  f"it is undefined; repair the mesh")
    if not mesh.is_winding_consistent:
        raise MeshFileError(name, f"the {what}'s triangles are not consistently oriented")


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return text[0] if text else "(no message)"
