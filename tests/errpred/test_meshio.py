"""errpred.meshio: every mesh file read through one function that names the file."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from errpred.meshio import MeshFileError, load_mesh
from nc.errors import InputError


def _box():
    return trimesh.creation.box(extents=(4.0, 3.0, 2.0))


def test_binary_and_text_stl_load_alike(tmp_path):
    box = _box()
    binary, text = tmp_path / "b.stl", tmp_path / "t.stl"
    binary.write_bytes(trimesh.exchange.stl.export_stl(box))
    # a text STL needs charset_normalizer (trimesh's encoding guess), declared in pyproject
    text.write_text(trimesh.exchange.stl.export_stl_ascii(box))
    for p in (binary, text):
        m = load_mesh(p, closed=True)
        assert len(m.faces) == 12 and m.is_watertight
        assert m.volume == pytest.approx(24.0)


@pytest.mark.parametrize("content, expected", [
    (b"", "empty file"),
    (b"solid x\n  facet normal what\nendsolid\n", "no triangles|cannot read"),
    (bytes(range(256)) * 16, "no triangles|cannot read"),
])
def test_bad_files_name_the_file(tmp_path, content, expected):
    p = tmp_path / "stock.stl"
    p.write_bytes(content)
    with pytest.raises(MeshFileError, match=expected) as exc:
        load_mesh(p)
    assert str(exc.value).startswith(str(p)) and "\n" not in str(exc.value)
    assert isinstance(exc.value, InputError)


def test_missing_file_and_directory(tmp_path):
    with pytest.raises(MeshFileError, match="nope.stl: mesh file not found"):
        load_mesh(tmp_path / "nope.stl")
    with pytest.raises(MeshFileError, match="not found"):
        load_mesh(tmp_path)


def test_truncated_binary_stl(tmp_path):
    p = tmp_path / "cut.stl"
    p.write_bytes(trimesh.exchange.stl.export_stl(_box())[:300])
    with pytest.raises(MeshFileError, match="cut.stl"):
        load_mesh(p)


def test_open_mesh_refused_only_when_closed_is_asked(tmp_path):
    box = _box()
    p = tmp_path / "open.stl"
    trimesh.Trimesh(box.vertices, box.faces[:-1], process=False).export(p)
    assert len(load_mesh(p).faces) == 11
    with pytest.raises(MeshFileError, match="open.stl: the stock mesh is not watertight"):
        load_mesh(p, what="stock mesh", closed=True)


def test_coordinates_that_are_not_finite(tmp_path):
    box = _box()
    v = box.vertices.copy()
    v[2, 1] = np.nan
    p = tmp_path / "nan.stl"
    p.write_bytes(trimesh.exchange.stl.export_stl(trimesh.Trimesh(v, box.faces, process=False)))
    with pytest.raises(MeshFileError, match="nan.stl: .*not finite"):
        load_mesh(p)


def test_size_limit(tmp_path, monkeypatch):
    from errpred import constants as K

    p = tmp_path / "big.stl"
    p.write_bytes(trimesh.exchange.stl.export_stl(_box()))
    monkeypatch.setattr(K, "MAX_MESH_FILE_BYTES", 100)
    with pytest.raises(MeshFileError, match="MAX_MESH_FILE_BYTES"):
        load_mesh(p)


def test_a_closed_mesh_with_triangles_turned_the_wrong_way_is_refused_when_read(tmp_path):
    """A closed mesh has an inside (a design's part, a stock's material): one triangle
    turned against its neighbours is refused when the file is read, naming it, whether or
    not a closed mesh was asked for; the same mesh turned the right way loads."""
    box = _box()
    faces = box.faces.copy()
    faces[0] = faces[0][::-1]
    bad = tmp_path / "design.stl"
    bad.write_bytes(trimesh.exchange.stl.export_stl(
        trimesh.Trimesh(box.vertices, faces, process=False)))
    for closed in (False, True):
        with pytest.raises(MeshFileError, match="not consistently oriented") as exc:
            load_mesh(bad, what="design mesh", closed=closed)
        assert str(exc.value).startswith(str(bad))
    good = tmp_path / "good.stl"
    good.write_bytes(trimesh.exchange.stl.export_stl(box))
    assert load_mesh(good, what="design mesh").is_winding_consistent
