"""What `thermodrift compensate` must refuse before the first row: a limit that makes no sense, a damaged or
tampered package, a malformed probe file, an output folder that does not exist, an input without rows, an
unknown controller format. Each is one line on stderr, exit code 2, and nothing written to the controller."""

import json
import shutil

import numpy as np
import pytest

from thermodrift.core.cli import main

from test_compensator_safety import export, fitted


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    """A folder with a good package (``pkg``), the tiny recording (``tiny.csv``, ``tiny.yaml``) and a probe file."""
    from thermodrift.testing.data import tiny_recording

    root = tmp_path_factory.mktemp("refusals")
    model, X, y = fitted("mlr")
    export(model, X, y, root / "pkg")
    tiny_recording(seed=0).write(root / "tiny.csv", root / "tiny.yaml")
    (root / "probe.csv").write_text("time_s,target,um\n600,disp_z_um,3.5\n")
    return root


def _tamper(folder, change):
    doc = json.loads((folder / "package.json").read_text())
    change(doc)
    (folder / "package.json").write_text(json.dumps(doc))


def _arrays(folder, **arrays):
    with np.load(folder / "arrays.npz") as npz:
        kept = {k: npz[k] for k in npz.files}
    np.savez(folder / "arrays.npz", **{**kept, **arrays})


def _deep(folder):
    (folder / "package.json").write_text('{"format": "thermodrift-compensator/1", "model": ' + "[" * 100000
                                         + "]" * 100000 + "}")


def _garbage_probe(root):
    (root / "bad_probe.csv").write_bytes(b"\xff\xfe\x00garbage\x81\n")


# name -> (extra options, what to do to the copied package (or None), what to do to the folder (or None))
CASES = {
    "max_step_negative": (["--max-step-um", "-1"], None, None),
    "max_step_zero": (["--max-step-um", "0"], None, None),
    "max_step_nan": (["--max-step-um", "nan"], None, None),
    "max_step_inf": (["--max-step-um", "inf"], None, None),
    "clamp_negative": (["--clamp-um", "-5"], None, None),
    "clamp_zero": (["--clamp-um", "0"], None, None),
    "clamp_nan": (["--clamp-um", "nan"], None, None),
    "detection_unit_zero": (["--detection-unit-um", "0", "--cnc", "fanuc"], None, None),
    "ipo_cycle_negative": (["--ipo-cycle-ms", "-4", "--cnc", "siemens"], None, None),
    "velo_factor_zero": (["--velo-factor", "0", "--cnc", "siemens"], None, None),
    "axis_velo_nan": (["--max-axis-velo-mm-min", "nan", "--cnc", "siemens"], None, None),
    "reference_inf": (["--reference-mm", "inf", "--cnc", "beckhoff"], None, None),
    "json_list": ([], lambda p: (p / "package.json").write_text("[1, 2, 3]"), None),
    "json_broken": ([], lambda p: (p / "package.json").write_text('{"format": '), None),
    "no_arrays_npz": ([], lambda p: (p / "arrays.npz").unlink(), None),
    "missing_array": ([], lambda p: _tamper(p, lambda d: d["model"].update(coef={"$array": "a99"})), None),
    "deep_nesting": ([], _deep, None),
    "pickled_array": ([], lambda p: _arrays(p, a2=np.array([{"x": 1}, None], dtype=object)), None),
    "text_array": ([], lambda p: _arrays(p, a2=np.array(["a", "b"])), None),
    "npz_not_a_zip": ([], lambda p: (p / "arrays.npz").write_bytes(b"not a zip archive"), None),
    "model_not_an_object": ([], lambda p: _tamper(p, lambda d: d.update(model=5)), None),
    "coef_wrong_shape": ([], lambda p: _arrays(p, a2=np.ones((7, 3))), None),
    "safety_input_missing": ([], lambda p: _tamper(p, lambda d: d["safety"]["input_low"].pop("T_column")), None),
    "float_garbage": ([], lambda p: _tamper(p, lambda d: d.update(sampling_interval_s={"$float": "lots"})), None),
    "probe_time_text": (["--probe", "bad_probe.csv"], None,
                        lambda r: (r / "bad_probe.csv").write_text("time_s,target,um\nsoon,disp_z_um,3\n")),
    "probe_um_text": (["--probe", "bad_probe.csv"], None,
                      lambda r: (r / "bad_probe.csv").write_text("time_s,target,um\n60,disp_z_um,three\n")),
    "probe_not_text": (["--probe", "bad_probe.csv"], None, _garbage_probe),
    "out_folder_missing": (["--out", "nowhere/v.csv"], None, None),
    "audit_folder_missing": (["--audit", "nowhere/audit.jsonl"], None, None),
    "header_only": (["--input", "empty.csv"], None,
                    lambda r: (r / "empty.csv").write_text((r / "tiny.csv").read_text().splitlines()[0] + "\n")),
    "cnc_unknown": (["--cnc", "semens"], None, None),
}


def _compensate(cwd, options, capsys, monkeypatch):
    args = {"--input": "tiny.csv", "--manifest": "tiny.yaml", "--out": "v.csv"}
    extra = list(options)
    for key in list(args):
        if key in extra:
            i = extra.index(key)
            args[key] = extra.pop(i + 1)
            extra.pop(i)
    monkeypatch.chdir(cwd)
    argv = ["compensate", "pkg", *[x for kv in args.items() for x in kv], *extra]
    try:
        rc = main(argv)
    except SystemExit as exc:  # argparse's usage block
        rc = exc.code
    return rc, capsys.readouterr().err, args["--out"]


@pytest.mark.parametrize("case", list(CASES))
def test_refused_in_one_line_with_exit_2_and_nothing_written(base, tmp_path, case, capsys, monkeypatch):
    options, on_package, on_folder = CASES[case]
    cwd = tmp_path / "cwd"
    shutil.copytree(base, cwd)
    if on_package:
        on_package(cwd / "pkg")
    if on_folder:
        on_folder(cwd)
    rc, err, out = _compensate(cwd, options, capsys, monkeypatch)
    lines = [line for line in err.splitlines() if line.strip()]
    assert rc == 2 and len(lines) == 1 and lines[0].startswith("thermodrift: error: "), err
    assert not (cwd / out).exists() and not (cwd / "audit.jsonl").exists()
    if case == "cnc_unknown":
        assert "did you mean 'siemens'" in lines[0]


def test_a_good_package_still_compensates_and_says_what_it_wrote(base, tmp_path, capsys, monkeypatch):
    cwd = tmp_path / "cwd"
    shutil.copytree(base, cwd)
    rc, err, _ = _compensate(cwd, ["--probe", "probe.csv", "--cnc", "fanuc", "--audit", "audit.jsonl"], capsys,
                             monkeypatch)
    assert rc == 0, err
    rows = (cwd / "v.csv").read_text().splitlines()
    assert rows[0].startswith("time_s,disp_z_um_units") and len(rows) > 100
    assert len((cwd / "audit.jsonl").read_text().splitlines()) == len(rows) - 1
