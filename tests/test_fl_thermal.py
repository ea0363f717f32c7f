"""The real FL_THERMAL recording through the fl_thermal dataset plugin, its Parquet cache and the CLI.

The workbook is never shipped; it is read from ../shared/data (or $THERMODRIFT_FL_THERMAL).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from omegaconf import OmegaConf

from thermodrift.core import configs
from thermodrift.core.errors import InputError
from thermodrift.core.registry import Registry
from thermodrift.plugins.datasets import fl_thermal as plugin

REPO = Path(__file__).parents[1]
WORKBOOK = Path(os.environ.get(plugin.ENV_PATH) or REPO.parent / "shared" / "data" / "fl_thermal" / "data.xlsx")
MANIFEST = REPO / "plugins" / "datasets" / "fl_thermal.yaml"
pytestmark = pytest.mark.skipif(not WORKBOOK.is_file(), reason=f"FL_THERMAL workbook not available at {WORKBOOK}")

LABELS = ["c00_idle", "c01_1250rpm", "c02_2500rpm", "c03_3750rpm", "c04_5000rpm", "c05_3500rpm", "c06_500rpm",
          "c07_1500rpm", "c08_2500rpm", "c09_4500rpm"]


@pytest.fixture(scope="module")
def cli_validate():
    """`thermodrift validate` on the workbook itself, started first so it parses the XLSX alongside the tests."""
    proc = subprocess.Popen([str(Path(sys.executable).with_name("thermodrift")), "validate", str(WORKBOOK),
                             "--manifest", str(MANIFEST)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    yield proc
    proc.kill()
    proc.wait()


@pytest.fixture(scope="module")
def cache_dir(tmp_path_factory):
    path = tmp_path_factory.mktemp("cache")
    old = os.environ.get("THERMODRIFT_CACHE_DIR")
    os.environ["THERMODRIFT_CACHE_DIR"] = str(path)
    yield path
    if old is None:
        del os.environ["THERMODRIFT_CACHE_DIR"]
    else:
        os.environ["THERMODRIFT_CACHE_DIR"] = old


@pytest.fixture(scope="module")
def rec(cli_validate, cache_dir):
    registry = Registry()
    plugin.thermodrift_register_datasets(registry)
    return registry.create("dataset", "fl_thermal", path=str(WORKBOOK))


def test_shape_channels_and_sampling(rec):
    assert len(rec) == 11_115 and rec.source == str(WORKBOOK)
    assert rec.temperatures.shape[1] == 16 and rec.displacements.shape[1] == 5
    assert rec.columns("speed") == ["spindle(RPM)"]
    assert rec.sampling_interval_s == 15.0 and rec.is_regular
    assert rec.time_s[0] == 0.0 and rec.time_s[-1] == 166_710.0
    assert rec.channels["ch3(um)"].meta == {"axis": "z"} and rec.channels["ch4(um)"].meta == {"axis": "z"}
    assert 43.0 < rec.data["t5(°C)"].max() < 44.0  # the hottest sensor, as documented
    assert rec.notes == []


def test_conditions_follow_the_speed_programme(rec):
    spans = rec.condition_spans()
    assert spans["label"].tolist() == LABELS
    block = spans.set_index("label").loc["c04_5000rpm"]
    assert block.start_s / 3600 == pytest.approx(24.13, abs=0.01)
    assert block.end_s / 3600 == pytest.approx(32.13, abs=0.01)
    # The block runs from the first 5000 rpm sample to the first sample of the next run (3500 rpm).
    speed = rec.speed.to_numpy()
    first_5000, first_3500 = rec.time_s[np.argmax(speed == 5000)], rec.time_s[np.argmax(speed == 3500)]
    window = (rec.time_s >= first_5000) & (rec.time_s < first_3500)
    np.testing.assert_array_equal(rec.conditions().to_numpy() == "c04_5000rpm", window)
    speeds = rec.speed[rec.conditions() == "c04_5000rpm"]
    assert set(np.unique(speeds)) == {0.0, 5000.0}


def test_second_load_reads_the_parquet_cache(rec, cache_dir):
    cached = list(cache_dir.glob("fl_thermal-*.parquet"))
    assert len(cached) == 1 and str(WORKBOOK.stat().st_size) in cached[0].name
    again = plugin.fl_thermal(str(WORKBOOK.parent))  # a folder holding data.xlsx works too
    assert again.data.equals(rec.data) and again.source == str(WORKBOOK)


def test_missing_workbook_says_where_to_get_it(tmp_path, monkeypatch):
    with pytest.raises(InputError, match="FL_THERMAL workbook not found.*CAIVIAC/FL_THERMAL") as caught:
        plugin.fl_thermal(str(tmp_path / "data.xlsx"))
    assert str(tmp_path / "data.xlsx") in str(caught.value)
    monkeypatch.setenv(plugin.ENV_PATH, str(tmp_path / "elsewhere.xlsx"))
    with pytest.raises(InputError, match=f"\\${plugin.ENV_PATH}"):
        plugin.fl_thermal()


def test_default_path_is_relative_to_the_working_directory(rec, monkeypatch):
    monkeypatch.delenv(plugin.ENV_PATH, raising=False)
    monkeypatch.chdir(WORKBOOK.parents[2])  # ../shared/data/fl_thermal/data.xlsx from <root>/shared
    assert len(plugin.fl_thermal()) == len(rec)


def test_config_names_the_plugin():
    registry = Registry()
    plugin.thermodrift_register_datasets(registry)
    conf = OmegaConf.create(configs.node(registry.get("dataset", "fl_thermal")))  # generated from the class
    assert conf.name == "fl_thermal" and conf.params.path is None


def test_cli_validate_prints_the_summary(cli_validate, rec):
    out, err = cli_validate.communicate(timeout=300)
    assert cli_validate.returncode == 0, err
    assert "rows: 11115" in out and "sampling interval: 15 s (regular)" in out
    assert "temperature (16)" in out and "displacement (5)" in out
    assert "c04_5000rpm" in out and "(86865 s to 115665 s)" in out
