"""On-disk cache of contact tables: keyed by inputs, atomic, corrupt files rebuilt."""
import ast
import importlib
from pathlib import Path

import numpy as np
import pytest

from microconveyor_env.physics import contact_table as ct
from microconveyor_env.physics import table_cache as tc
from microconveyor_env.physics.materials import ContactParams



def _fresh(monkeypatch, tmp_path):
    monkeypatch.setenv("MICROCONVEYOR_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(tc, "_MEMO", {})


def test_key_depends_on_shape_inputs_not_on_calibration():
    p = ContactParams()
    k = ct.table_key(p, 0.01, 1e4)
    assert ct.table_key(p.replace(surface__beta=0.1, friction_scale=0.5), 0.01, 1e4) == k
    assert ct.table_key(p.replace(surface__sigma=21e-9), 0.01, 1e4) != k
    assert ct.table_key(p, 0.02, 1e4) != k


def test_table_written_once_and_reused(monkeypatch, tmp_path):
    _fresh(monkeypatch, tmp_path)
    p = ContactParams()
    t1 = ct.ContactTable(p, spacing=0.02)
    files = list(tmp_path.glob("ke-table-*.npz"))
    assert len(files) == 1 and not list(tmp_path.glob("*.tmp"))
    monkeypatch.setattr(tc, "_MEMO", {})
    monkeypatch.setattr(tc, "build_base_table", lambda *a, **k: (_ for _ in ()).throw(AssertionError))
    with pytest.raises(AssertionError):  # the patched builder is the one a cache miss calls
        ct.ContactTable(p, spacing=0.03)
    t2 = ct.ContactTable(p, spacing=0.02)  # must come from disk, not a rebuild
    np.testing.assert_array_equal(t1.base.q, t2.base.q)


def test_corrupt_cache_is_rebuilt_not_trusted(monkeypatch, tmp_path):
    _fresh(monkeypatch, tmp_path)
    p = ContactParams()
    good = ct.ContactTable(p, spacing=0.02).pull_off_force
    path = next(tmp_path.glob("ke-table-*.npz"))
    for garbage in (b"not a zip file", path.read_bytes()[:200]):
        path.write_bytes(garbage)
        monkeypatch.setattr(tc, "_MEMO", {})
        assert ct.ContactTable(p, spacing=0.02).pull_off_force == good
    # a readable file with wrong content (NaN) is rejected too
    key = ct.table_key(p, 0.02, ct.DEFAULT_LOAD_RATIO)
    t = ct.build_base_table(p, spacing=0.02)
    arrays = t.arrays()
    arrays["q"] = np.full_like(arrays["q"], np.nan)
    np.savez(path, key=np.array(key), **arrays)
    assert tc._load_cached(path, key) is None
    monkeypatch.setattr(tc, "_MEMO", {})
    assert np.all(np.isfinite(ct.ContactTable(p, spacing=0.02).base.q))


def test_unwritable_cache_still_works(monkeypatch, tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    _fresh(monkeypatch, blocker / "sub")  # cannot create a directory under a file
    assert ct.ContactTable(ContactParams(), spacing=0.02).pull_off_force > 0


def test_contact_table_reexports_the_cache():
    """contact_table re-exports the cache's public names; the memory cache and the builder are
    looked up in table_cache, so that is where these tests replace them (patching ct changes
    nothing)."""
    assert ct.build_base_table is tc.build_base_table
    assert ct.base_table is tc.base_table and ct.table_key is tc.table_key


def _table_modules():
    """The physics modules the contact table's numbers (or its cache) come from: contact_table,
    the builder and the cache, and every physics module they import, directly or not."""
    physics = Path(ct.__file__).parent
    todo, seen = ["contact_table", "table_build", "table_cache"], set()
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        seen.add(name)
        for node in ast.walk(ast.parse((physics / f"{name}.py").read_text())):
            if isinstance(node, ast.ImportFrom) and node.level == 1:
                todo += [node.module] if node.module else [a.name for a in node.names]
    return sorted(seen)


@pytest.mark.parametrize("module", _table_modules())
def test_key_depends_on_the_source_of_every_table_module(monkeypatch, module):
    """An edit of any module the table comes from changes the key, so a stale table is never
    loaded (without relying on someone bumping TABLE_FORMAT)."""
    path = Path(importlib.import_module(f"microconveyor_env.physics.{module}").__file__).resolve()
    p = ContactParams()
    key = ct.table_key(p, 0.01, 1e4)
    read_bytes = Path.read_bytes

    def edited(self):
        return read_bytes(self) + (b"# edit" if self.resolve() == path else b"")

    monkeypatch.setattr(Path, "read_bytes", edited)
    tc._code_hash.cache_clear()
    try:
        assert ct.table_key(p, 0.01, 1e4) != key
    finally:
        monkeypatch.undo()
        tc._code_hash.cache_clear()
    assert ct.table_key(p, 0.01, 1e4) == key


def test_key_depends_on_quadrature_settings(monkeypatch):
    from microconveyor_env.physics import rough_surface

    p = ContactParams()
    k = ct.table_key(p, 0.01, 1e4)
    monkeypatch.setattr(rough_surface, "GL_ORDER", rough_surface.GL_ORDER + 2)
    assert ct.table_key(p, 0.01, 1e4) != k


def _tampered(arrays, how):
    a = {k: np.array(v, copy=True) for k, v in arrays.items()}
    if how == "negative-friction":
        a["q"] = -a["q"]
    elif how == "shuffled-loads":
        a["n"] = a["n"][::-1].copy()
    elif how == "u-not-sqrt-of-n":
        a["u"] = a["u"] * 1.01
    elif how == "moved-pull-off":
        a["d_pull"] = a["d_pull"] + 0.5
    elif how == "positive-n-min":
        a["n_min"] = -a["n_min"]
    elif how == "short-arrays":
        a["q"] = a["q"][:-1]
    elif how == "2-d":
        a["q_u"] = np.stack([a["q_u"], a["q_u"]])
    return a


@pytest.mark.parametrize("how", ["negative-friction", "shuffled-loads", "u-not-sqrt-of-n",
                                 "moved-pull-off", "positive-n-min", "short-arrays", "2-d"])
def test_parseable_but_inconsistent_cache_is_rebuilt(monkeypatch, tmp_path, how):
    """A table file that loads fine but could not have come from the builder is not trusted."""
    _fresh(monkeypatch, tmp_path)
    p = ContactParams()
    good = ct.ContactTable(p, spacing=0.02)
    path = next(tmp_path.glob("ke-table-*.npz"))
    key = ct.table_key(p, 0.02, ct.DEFAULT_LOAD_RATIO)
    assert tc._load_cached(path, key) is not None
    np.savez(path, key=np.array(key), **_tampered(good.base.arrays(), how))
    assert tc._load_cached(path, key) is None
    monkeypatch.setattr(tc, "_MEMO", {})
    rebuilt = ct.ContactTable(p, spacing=0.02)
    np.testing.assert_array_equal(rebuilt.base.q, good.base.q)
    assert tc._load_cached(path, key) is not None  # and the good table was written back
