"""Recording layer: loading, units, gaps, condition detection, selection, round trips, dataset plugins."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import openpyxl
import pandas as pd
import pytest
from omegaconf import OmegaConf

from thermodrift.core import configs
from thermodrift.core.errors import InputError
from thermodrift.core.recording import Channel, Recording, detect_conditions, load_recording
from thermodrift.core.registry import Registry
from thermodrift.plugins.datasets import recording_file as recording_file_plugin

DATA = Path(__file__).parent / "data"
GOOD_TABLE, GOOD_MANIFEST = DATA / "good" / "recording.csv", DATA / "good" / "recording.yaml"


def write_manifest(path: Path, channels: dict[str, str], head: str = "time: time_s\n") -> Path:
    path.write_text(head + "channels:\n" + "".join(f"  {c}: {s}\n" for c, s in channels.items()), encoding="utf-8")
    return path


def schedule(blocks: list[tuple[float, float]], dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Time in s and a piecewise-constant speed in rpm from (rpm, duration s) blocks."""
    speed = np.concatenate([np.full(int(round(d / dt)), rpm, dtype=float) for rpm, d in blocks])
    return np.arange(len(speed)) * dt, speed


def spans(labels: np.ndarray, t: np.ndarray) -> list[tuple[str, float]]:
    starts = np.flatnonzero(np.r_[True, labels[1:] != labels[:-1]])
    return [(str(labels[i]), float(t[i])) for i in starts]


def test_good_csv_loads_channels_by_role_in_canonical_units():
    rec = load_recording(GOOD_TABLE, GOOD_MANIFEST)
    table = pd.read_csv(GOOD_TABLE)
    assert len(rec) == 40 and rec.data.index.name == "time_s"
    np.testing.assert_array_equal(rec.time_s, table["time_s"].to_numpy(dtype=float))
    assert rec.columns("temperature") == ["T1", "T2", "T3"]
    assert list(rec.displacements.columns) == ["disp_z_um"] and rec.columns("ambient") == ["ambient_C"]
    np.testing.assert_allclose(rec.temperatures.to_numpy(), table[["T1", "T2", "T3"]].to_numpy())
    assert rec.speed is not None and rec.speed.name == "spindle_rpm"
    assert rec.channels["T1"] == Channel("T1", "temperature", "degC", {"location": "front_bearing"})
    assert rec.channels["disp_z_um"].meta == {"axis": "z"}
    assert rec.sampling_interval_s == 15.0 and rec.is_regular
    assert rec.notes == [] and rec.source == str(GOOD_TABLE)


def test_units_are_converted_to_canonical(tmp_path):
    n = 12
    t_min = np.arange(n) * 0.25
    table = pd.DataFrame({"t_min": t_min, "T_K": 293.15 + 0.1 * np.arange(n), "d_mm": -0.001 * np.arange(n),
                          "w_rad_s": np.full(n, 2 * math.pi * 50), "p_kW": np.linspace(1, 2, n),
                          "v_m_min": np.linspace(0, 12, n), "amb_K": np.full(n, 293.15)})
    table.to_csv(tmp_path / "r.csv", index=False)
    write_manifest(tmp_path / "r.yaml", {
        "T_K": "{role: temperature, unit: K}", "d_mm": "{role: displacement, unit: mm}",
        "w_rad_s": "{role: speed, unit: rad_s}", "p_kW": "{role: cutting_power, unit: kW}",
        "v_m_min": "{role: axis_velocity, unit: m_min}", "amb_K": "{role: ambient, unit: K}"},
        head="time: t_min\ntime_unit: min\n")
    rec = load_recording(tmp_path / "r.csv", tmp_path / "r.yaml")
    np.testing.assert_allclose(rec.time_s, t_min * 60)
    np.testing.assert_allclose(rec.data["T_K"], 20.0 + 0.1 * np.arange(n), atol=1e-9)
    np.testing.assert_allclose(rec.data["d_mm"], -1.0 * np.arange(n), atol=1e-9)
    np.testing.assert_allclose(rec.data["w_rad_s"], 3000.0)
    np.testing.assert_allclose(rec.data["p_kW"], 1000 * np.linspace(1, 2, n))
    np.testing.assert_allclose(rec.data["v_m_min"], 1000 * np.linspace(0, 12, n))
    assert {ch.unit for ch in rec.channels.values()} == {"degC", "um", "rpm", "W", "mm_min"}
    assert sum("converted from" in note for note in rec.notes) == 6  # constant ambient is legitimate


def test_timestamps_become_seconds_from_start_csv_and_xlsx(tmp_path):
    stamps = pd.date_range("2024-05-01 08:00:00", periods=20, freq="30s")
    t = np.arange(20) * 30.0
    frame = pd.DataFrame({"when": stamps, "T1": 20 + 0.01 * t, "d": -0.001 * t})
    frame.assign(when=stamps.strftime("%Y-%m-%dT%H:%M:%S")).to_csv(tmp_path / "r.csv", index=False)
    frame.to_excel(tmp_path / "r.xlsx", index=False)
    manifest = write_manifest(tmp_path / "r.yaml", {"T1": "{role: temperature, unit: degC}",
                                                    "d": "{role: displacement, unit: um}"}, head="time: when\n")
    for table in ("r.csv", "r.xlsx"):
        np.testing.assert_allclose(load_recording(tmp_path / table, manifest).time_s, t)


def test_columns_not_in_manifest_are_ignored_with_a_note(tmp_path):
    table = pd.read_csv(GOOD_TABLE).assign(extra_1=1.0, extra_2="x")
    table.to_csv(tmp_path / "r.csv", index=False)
    rec = load_recording(tmp_path / "r.csv", GOOD_MANIFEST)
    assert "extra_1" not in rec.data.columns
    assert any("extra_1, extra_2" in note and "ignored 2 column" in note for note in rec.notes)
    assert "extra_1" in rec.summary()


def test_isolated_missing_values_are_interpolated_in_time(tmp_path):
    table = pd.read_csv(GOOD_TABLE)
    expected = table["T2"].to_numpy().copy()
    t = table["time_s"].to_numpy(dtype=float)
    table.loc[[0, 5, 20, 21, 22], "T2"] = np.nan  # a leading NaN, a single one and a run of three
    table.to_csv(tmp_path / "r.csv", index=False)
    rec = load_recording(tmp_path / "r.csv", GOOD_MANIFEST)
    got = rec.data["T2"].to_numpy()
    assert got[0] == expected[1]  # no left neighbour: the nearest value
    assert got[5] == pytest.approx(np.interp(t[5], t[[4, 6]], expected[[4, 6]]))
    np.testing.assert_allclose(got[20:23], np.interp(t[20:23], t[[19, 23]], expected[[19, 23]]))
    assert any(n.startswith("T2: 5 missing value(s) interpolated") and "rows 2, 7, 22" in n for n in rec.notes)


def test_semicolon_csv_with_quoted_header_and_spaces(tmp_path):
    text = GOOD_TABLE.read_text(encoding="utf-8").replace(",", ";").replace("T1", '" T1 "', 1)
    (tmp_path / "r.csv").write_text(text, encoding="utf-8")
    rec = load_recording(tmp_path / "r.csv", GOOD_MANIFEST)
    np.testing.assert_allclose(rec.data["T1"], pd.read_csv(GOOD_TABLE)["T1"])


def test_xlsx_sheet_is_chosen_by_manifest(tmp_path):
    book = openpyxl.Workbook()
    book.active.title = "notes"
    book.active.append(["written by hand"])
    sheet = book.create_sheet("run 2")
    table = pd.read_csv(GOOD_TABLE)
    for row in [list(table.columns), *table.itertuples(index=False)]:
        sheet.append(list(row))
    book.save(tmp_path / "r.xlsx")
    (tmp_path / "r.yaml").write_text("sheet: run 2\n" + GOOD_MANIFEST.read_text(encoding="utf-8"), encoding="utf-8")
    rec = load_recording(tmp_path / "r.xlsx", tmp_path / "r.yaml")
    assert len(rec) == 40
    with pytest.raises(InputError, match="sheet 'notes' has a header but no data rows"):  # default: first sheet
        load_recording(tmp_path / "r.xlsx", GOOD_MANIFEST)


@pytest.mark.parametrize("suffix", [".csv", ".parquet", ".xlsx"])
def test_write_then_load_round_trips(tmp_path, suffix):
    t = np.arange(30) * 10.0 + 5.0
    data = pd.DataFrame({"T_spindle": 20 + 0.03 * t, "drift": -0.01 * t, "rpm": np.where(t < 150, 1000.0, 2000.0),
                         "phase": np.where(t < 150, "a", "b")}, index=t)
    channels = {"T_spindle": Channel("T_spindle", "temperature", "degC", {"location": "nose"}),
                "drift": Channel("drift", "displacement", "um", {"axis": "z"}),
                "rpm": Channel("rpm", "speed", "rpm"), "phase": Channel("phase", "condition", None)}
    original = Recording(data, channels)
    original.write(tmp_path / f"r{suffix}", tmp_path / "r.yaml")
    loaded = load_recording(tmp_path / f"r{suffix}", tmp_path / "r.yaml")
    pd.testing.assert_frame_equal(loaded.data, original.data, check_dtype=False)
    assert loaded.channels == original.channels
    assert list(loaded.conditions()) == ["a"] * 15 + ["b"] * 15  # the condition channel wins over speed


def test_detection_stop_joins_previous_restart_continues_leading_idle_is_own():
    t, speed = schedule([(0, 600), (1250, 3600), (0, 1800), (2500, 3600), (0, 600), (2500, 1800), (500, 1800),
                         (0, 900)], dt=15.0)
    rng = np.random.default_rng(0)
    noisy = speed + rng.normal(0.0, 5.0, len(speed))
    noisy[[500, 900, 901]] = [0.0, 5000.0, 0.0]  # encoder dropouts and a spike inside running blocks
    labels = detect_conditions(t, noisy)
    assert spans(labels, t) == [("c00_idle", 0.0), ("c01_1250rpm", 600.0), ("c02_2500rpm", 6000.0),
                                ("c03_500rpm", 12000.0)]


def test_detection_ramps_join_the_level_they_reach():
    t, speed = schedule([(0, 300), (3000, 600), (0, 300)], dt=1.0)
    speed[300:330] = np.linspace(0, 3000, 30)  # 30 s run-up at 1 Hz sampling
    speed[900:920] = np.linspace(3000, 0, 20)
    got = spans(detect_conditions(t, speed), t)
    assert [label for label, _ in got] == ["c00_idle", "c01_3000rpm"]
    assert 300.0 <= got[1][1] <= 330.0


def test_constant_speed_is_one_condition_and_no_speed_gives_one_label():
    t, speed = schedule([(1800, 3600)], dt=30.0)
    assert set(detect_conditions(t, speed)) == {"c01_1800rpm"}
    assert set(detect_conditions(t, np.zeros_like(t))) == {"c00_idle"}
    rec = Recording(pd.DataFrame({"T": 20 + t / 1e4, "d": t / 1e3}, index=t),
                    {"T": Channel("T", "temperature", "degC"), "d": Channel("d", "displacement", "um")})
    assert set(rec.conditions()) == {"c01_all"}


def two_speed_runs() -> Recording:
    t, speed = schedule([(0, 900), (2000, 1800), (0, 900), (4000, 1800)], dt=15.0)
    data = pd.DataFrame({"T": 20 + speed / 1e3, "d": -speed / 1e2, "n": speed}, index=t)
    return Recording(data, {"T": Channel("T", "temperature", "degC"), "d": Channel("d", "displacement", "um"),
                            "n": Channel("n", "speed", "rpm")}, source="synthetic")


def test_condition_spans_are_half_open_and_summary_lists_them():
    rec = two_speed_runs()
    table = rec.condition_spans()
    assert table["label"].tolist() == ["c00_idle", "c01_2000rpm", "c02_4000rpm"]
    assert table["start_s"].tolist() == [0.0, 900.0, 3600.0] and table["end_s"].tolist() == [900.0, 3600.0, 5400.0]
    text = rec.summary()
    assert "file: synthetic" in text and "rows: 360" in text and "sampling interval: 15 s (regular)" in text
    assert "c01_2000rpm" in text and "(900 s to 3600 s)" in text and "n [rpm]: 0 to 4000" in text


def test_select_keeps_labels_of_the_whole_recording():
    rec = two_speed_runs()
    later = rec.select(rec.time_s >= 3000)
    assert later.time_s[0] == 3000.0  # time is not re-zeroed
    assert later.conditions().iloc[0] == "c01_2000rpm"  # detected on the whole, not re-detected on the part
    by_position = rec.select([0, 1, 300])
    assert by_position.conditions().tolist() == ["c00_idle", "c00_idle", "c02_4000rpm"]
    with pytest.raises(ValueError, match="boolean mask"):
        rec.select(np.ones(3, dtype=bool))


def test_recording_rejects_data_that_disagrees_with_channels():
    data = pd.DataFrame({"T": [1.0, 2.0], "x": [0.0, 1.0]})
    with pytest.raises(ValueError, match="data without channel"):
        Recording(data, {"T": Channel("T", "temperature", "degC")})
    with pytest.raises(ValueError, match="role"):
        Recording(data[["T"]], {"T": Channel("T", "heat", "W")})


def test_require_can_drop_displacement(tmp_path):
    manifest = write_manifest(tmp_path / "r.yaml", {"T1": "{role: temperature, unit: degC}"})
    with pytest.raises(InputError, match="no channel has role displacement"):
        load_recording(GOOD_TABLE, manifest)
    assert load_recording(GOOD_TABLE, manifest, require=("temperature",)).columns("displacement") == []


def test_recording_file_plugin_registers_and_loads():
    registry = Registry()
    recording_file_plugin.thermodrift_register_datasets(registry)
    rec = registry.create("dataset", "recording_file", table=str(GOOD_TABLE), manifest=str(GOOD_MANIFEST))
    assert len(rec) == 40
    # The config Hydra composes for it is generated from the class (no shipped YAML restates it).
    conf = OmegaConf.create(configs.node(registry.get("dataset", "recording_file")))
    assert conf.name == "recording_file"
    assert OmegaConf.is_missing(conf.params, "table") and OmegaConf.is_missing(conf.params, "manifest")
