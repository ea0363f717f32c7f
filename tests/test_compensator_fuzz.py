"""Fuzzing what the compensator reads from outside: a package whose JSON and arrays are changed anywhere, an input
file of arbitrary bytes, rows of arbitrary cells. Every outcome is a package, a valid row, or one InputError;
and whatever the rows hold, the written values stay finite and inside the clamp."""

import io
import json
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from thermodrift import compensator
from thermodrift.compensator import stream
from thermodrift.compensator.cnc import writer
from thermodrift.compensator.errors import InputError

from test_compensator_safety import export, fitted

FUZZ = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])

json_values = st.recursive(
    st.none() | st.booleans() | st.integers(-10**6, 10**6) | st.floats() | st.text(max_size=8)
    | st.sampled_from([{"$array": "a0"}, {"$array": "a9"}, {"$array": 3}, {"$float": "nan"}, {"$float": "x"},
                       {"$tensor": "t0"}, {"$array": "a1", "more": 1}]),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=6), inner, max_size=4),
    max_leaves=12)


@pytest.fixture(scope="module")
def good(tmp_path_factory):
    folder = tmp_path_factory.mktemp("good")
    model, X, y = fitted("mlr")
    pkg = export(model, X, y, folder / "pkg")
    return folder / "pkg", pkg


def _paths(tree, prefix=()):
    """Every path (tuple of keys and indices) into a JSON tree."""
    yield prefix
    items = tree.items() if isinstance(tree, dict) else enumerate(tree) if isinstance(tree, list) else ()
    for key, value in items:
        yield from _paths(value, (*prefix, key))


def _outcome(folder):
    try:
        return compensator.load(folder)
    except InputError as exc:
        assert "\n" not in str(exc) and str(exc)
        return exc


@FUZZ
@given(data=st.data())
def test_a_changed_package_loads_or_is_refused_with_one_input_error(good, data):
    folder, _ = good
    doc = json.loads((folder / "package.json").read_text())
    paths = list(_paths(doc))
    for _ in range(data.draw(st.integers(1, 3))):
        path = data.draw(st.sampled_from(paths))
        if not path:
            doc = data.draw(json_values)
            break
        parent = doc
        for key in path[:-1]:
            parent = parent[key]
        if data.draw(st.booleans()) and isinstance(parent, dict):
            parent.pop(path[-1], None)
        else:
            parent[path[-1]] = data.draw(json_values)
        paths = list(_paths(doc))
    with tempfile.TemporaryDirectory() as tmp:
        copy = Path(tmp) / "pkg"
        shutil.copytree(folder, copy)
        (copy / "package.json").write_text(json.dumps(doc))
        if data.draw(st.booleans()):  # and an array of another shape or type
            shape = data.draw(st.lists(st.integers(0, 5), max_size=3))
            dtype = data.draw(st.sampled_from(["float64", "int8", "bool", "complex64", "<U2"]))
            key = data.draw(st.sampled_from(["a0", "a1", "a2", "a3"]))
            with np.load(copy / "arrays.npz") as npz:
                arrays = {k: npz[k] for k in npz.files}
            arrays[key] = np.zeros(shape, dtype=dtype)
            np.savez(copy / "arrays.npz", **arrays)
        result = _outcome(copy)
    assert isinstance(result, (compensator.Package, InputError))


@FUZZ
@given(blob=st.binary(max_size=300) | st.text(max_size=300).map(str.encode))
def test_an_input_file_of_any_bytes_opens_or_is_refused(blob):
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "in.csv"
        path.write_bytes(blob)
        try:
            header, rows = stream.open_rows(str(path))
            body = list(rows)
        except InputError as exc:
            assert "\n" not in str(exc)
            return
    assert all(isinstance(c, str) for c in header) and len(body) >= 1 and all(isinstance(r, list) for r in body)


cells = st.one_of(st.text(max_size=10), st.none(), st.floats(), st.integers(-10**30, 10**30),
                  st.sampled_from(["", "nan", "inf", "-1e999", "1e999", " 21.5 ", "0x10", "1_0"]))


@FUZZ
@given(header=st.lists(st.sampled_from(["time_s", "T_front_bearing", "T_rear_bearing", "T_column", "T_cabinet",
                                         "other"]), max_size=7),
       rows=st.lists(st.lists(cells, max_size=8), min_size=1, max_size=15))
def test_rows_of_any_cells_parse_to_a_valid_row_and_write_finite_clamped_values(good, header, rows):
    _, pkg = good
    try:
        parse = stream.Rows(header, "time_s", 1.0, pkg.inputs, {c: (1.0, 0.0) for c in pkg.inputs}, "in.csv")
    except InputError as exc:
        assert "column not found" in str(exc)
        return
    for cells in rows:
        t, values = parse.parse(cells)
        assert isinstance(t, float) and values.shape == (len(pkg.inputs),) and values.dtype == float
    comp = pkg.compensator()
    out = io.StringIO()
    n = stream.run(comp, writer(pkg, "csv"), rows, parse, out)
    written = np.array([[float(v) for v in line.split(",")[1::3]] for line in out.getvalue().splitlines()[1:]])
    assert n == len(rows) and written.shape == (len(rows), len(pkg.targets))
    assert np.isfinite(written).all() and (np.abs(written) <= comp.clamp + 1e-12).all()
