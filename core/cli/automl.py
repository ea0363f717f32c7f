"""``thermodrift automl [overrides]``: ``thermodrift run automl=default [overrides]``, the search across families.

The same Hydra config groups, overrides, checks and did-you-mean answers as ``run`` (dataset, split, targets,
seed, tracking, optuna.storage, progress); the model, selector and optimizer groups are not used: the search
chooses. Settings are ``automl.<key>=<value>`` (``conf/automl/default.yaml``). In MLflow: one run tagged
``kind=automl`` (held-out metrics as ``run`` logs them, ``leaderboard.csv`` and ``leaderboard.md`` at the artifact
root, the chosen pipeline's parameters, the pipeline as ``model``), with one child run per family tried, tagged
``kind=automl_candidate``. This module holds its ``--help`` only (no import of Hydra, MLflow or torch); the job
runs in the Hydra app of :mod:`thermodrift.core.cli.run`.
"""

from __future__ import annotations

USAGE = """usage: thermodrift automl [KEY=VALUE ...] [GROUP=OPTION ...] [automl.KEY=VALUE ...]

Searches selector (with its settings, or all sensors) x input features (raw, or filtered temperatures and drive
heat terms) x model family (every registered model, plugins included) x the family's settings. Inner validation
predicts each later working condition of the training part from the earlier ones; the best pipeline (or a greedy
ensemble, when it is better there) is refitted on the training part and scored once on the held-out part beside
persistence and MLR, in MLflow (a run tagged kind=automl with leaderboard.csv). Budget: automl.budget_fits
(deterministic; default 120) or also automl.timeout_s (s, load-dependent). A re-run with the same storage resumes.

examples:
  thermodrift automl dataset=fl_thermal split=time_window split.params.train_end_h=24.13 \\
      split.params.test_start_h=24.13 split.params.test_end_h=32.13 "targets=['ch3(um)']"
  thermodrift automl experiment=fl_thermal_5000rpm_heldout automl.budget_fits=60
  thermodrift automl dataset=recording_file dataset.params.table=my.csv dataset.params.manifest=my.yaml
  thermodrift automl "automl.families=[mlr,transfer_function,lptn_hybrid]" seed=1

automl settings (automl.KEY=VALUE):"""


def help_text() -> str:
    """``thermodrift automl --help``: its usage, its settings, then the groups and keys it shares with ``run``."""
    from importlib import resources

    from thermodrift.core.cli import run_options

    lines = [USAGE]
    text = resources.files("thermodrift.conf.automl").joinpath("default.yaml").read_text(encoding="utf-8")
    for line in text.splitlines():
        if line and not line.startswith("#"):
            key, _, rest = line.partition(":")
            value, _, doc = rest.partition("#")
            lines.append(f"  {key:<16}{value.strip():<10} {doc.strip()}")
    shared = run_options.help_text().split("\n\n", 3)[-1]
    return "\n".join(lines) + "\n\nshared with thermodrift run:\n" + shared
