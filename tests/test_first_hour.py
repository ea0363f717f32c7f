"""A newcomer's first hour: what the first commands print, one line per problem, and what the README promises."""

from __future__ import annotations

import re
import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import pytest

from thermodrift.core import registry

REPO = Path(__file__).parents[1]
TINY = ["dataset=recording_file", "dataset.params.table=tiny.csv", "dataset.params.manifest=tiny.yaml"]


def test_the_default_job_tunes_a_model_that_is_not_one_of_its_baselines():
    from thermodrift.core.cli import run_options

    keys = {k.path: k.default for k in run_options.keys()}
    model = run_options.defaults()["model"]
    assert model not in re.findall(r"\w+", keys["baselines"])
    assert registry.get("model", model).factory.search_space()  # something to tune


@pytest.mark.parametrize("verb, flag, hint", [("run", "--n-trials", "n_trials=5"),
                                              ("automl", "--budget", "automl.budget_fits=5"),
                                              ("run", "--n_trials=5", "n_trials=5")])
def test_a_double_dash_setting_is_answered_in_one_line_with_the_override(tmp_path, cli, verb, flag, hint):
    started = time.perf_counter()
    out = cli(tmp_path, verb, *([flag] if "=" in flag else [flag, "5"]))
    assert out.returncode == 2 and out.stdout == ""
    (line,) = out.stderr.strip().splitlines()
    assert line.startswith("thermodrift: error:") and hint in line
    assert time.perf_counter() - started < 20  # before Hydra composes anything
    assert not (tmp_path / "outputs").exists()


def test_a_job_without_a_terminal_writes_no_bar_and_counts_the_trials_it_runs(workdir, cli):
    """stderr to a file: no carriage returns; a model with nothing to tune runs one trial and says so."""
    out = cli(workdir, "run", *TINY, "model=persistence", "n_trials=20")
    assert out.returncode == 0, out.stderr[-2000:]
    assert "\r" not in out.stderr and "of 20 trials" not in out.stderr
    assert "1 of 1 trials finished" in out.stderr


def test_automl_without_a_terminal_writes_no_bar_and_names_its_baseline(workdir, cli):
    out = cli(workdir, "automl", *TINY, "automl.budget_fits=3", "automl.families=[mlr]")
    assert out.returncode == 0, out.stderr[-2000:]
    assert "\r" not in out.stderr
    assert "mlr baseline: MLR on every input temperature" in out.stdout
    assert re.search(r"^\s*rank\s+trial\s+model", out.stdout, re.M)  # the trial numbers the notes cite


def test_the_job_report_says_which_inputs_its_mlr_baseline_reads():
    from thermodrift.core.cli.run import job_report
    from thermodrift.core.study import Job, JobSpec
    from thermodrift.testing.data import tiny_recording

    spec = JobSpec(dataset="recording_file", model="mlr", selector="correlation_top_k", selector_params={"k": 2},
                   storage=None, progress=False, n_trials=0)
    result = Job(spec).run(tiny_recording())
    run = SimpleNamespace(info=SimpleNamespace(artifact_uri="file:///a", run_id="r"))
    text = job_report(result, run, "sqlite:///mlflow.db")
    assert f"mlr baseline: MLR on the {len(result.selected)} selected sensors" in text
    assert f"held-out ({result.folds[0].name.removeprefix('held out: ')})" in text and "held out" not in text


def test_plugins_piped_into_a_reader_that_stops_early_exits_quietly():
    for extra in ([], ["--json"]):
        proc = subprocess.Popen([sys.executable, "-m", "thermodrift.core.cli", "plugins", *extra],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        proc.stdout.close()  # the reader is gone before the first line (`| head -1` after its line)
        err = proc.stderr.read().decode()
        assert proc.wait(timeout=120) == 141, err  # 128 + SIGPIPE, as `yes | head -1`
        assert err == ""


def test_a_grid_with_one_jobs_config_is_one_line_and_exit_2(capsys):
    from thermodrift.core.cli import main

    assert main(["run", "-m", "model=mlr,persistence", "--cfg", "job"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("thermodrift: error: -m and --cfg:") and "\n" not in err
    assert "thermodrift run model=mlr --cfg job" in err
    assert main(["automl", "--cfg", "job", "--info"]) == 2
    assert "--cfg and --info" in capsys.readouterr().err


def test_a_finding_shows_its_values_and_never_an_empty_dict():
    from thermodrift.core.cli.diagnose import finding_line

    line = finding_line({"mechanism": "sensor_lag", "confidence": 1.0, "parameters": {}, "fixed": {"lag_s": 300.0},
                         "label": "sensor_lag (lag_s=300)"})
    assert line.endswith("sensor_lag (confidence 1.00): lag_s=300") and "{}" not in line
    bare = finding_line({"mechanism": "cutting_heat", "confidence": 0.5, "parameters": {}})
    assert bare.endswith(": no parameter to estimate")


def test_diagnose_help_names_the_correction_the_code_applies_as_the_readme_does(cli, tmp_path):
    out = cli(tmp_path, "diagnose", "--help")
    text = " ".join(out.stdout.split())
    assert "Benjamini-Hochberg" in text and "Bonferroni" not in text
    assert "Benjamini–Hochberg over the round's candidates" in (REPO / "README.md").read_text(encoding="utf-8")


def test_figure_titles_name_the_held_out_part_once():
    from thermodrift.core import tracking
    from thermodrift.core.study import Job, JobSpec
    from thermodrift.testing.data import tiny_recording

    result = Job(JobSpec(dataset="recording_file", model="mlr", storage=None, progress=False, n_trials=0)).run(
        tiny_recording())
    assert result.folds[-1].name.startswith("held out: ")
    for fig in tracking.figures(result).values():
        title = fig._suptitle.get_text() if fig._suptitle is not None else fig.axes[0].get_title()
        assert title.count("held out") <= 1, title


def test_plugins_describes_each_component_in_a_whole_sentence():
    from thermodrift.core.cli.plugins import describe

    line = describe(registry.get("model", "ensemble"))
    assert line.endswith("normalised to sum 1).")
    for kind in ("selector", "model", "optimizer"):
        for name in registry.names(kind):
            text = describe(registry.get(kind, name))
            assert text.count("(") == text.count(")"), (kind, name, text)


def test_the_readme_lists_every_benchmark_and_every_place_a_run_writes():
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    (listed,) = re.findall(r"without a name it lists them: ([^.|]+)", readme)
    names = {n.strip() for n in listed.split(",")}
    assert names == {p.stem.removeprefix("bench_") for p in (REPO / "benchmarks").glob("bench_*.py")}
    for place in ("mlflow.db", "mlruns/", "thermodrift.optuna.db", "outputs/<id>/"):
        assert f"`{place}`" in readme
