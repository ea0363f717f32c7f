"""S3's presets compose into the intended grid: eight arms under two protocols, five tagged ablations."""

from __future__ import annotations

from importlib.resources import files

import pytest
import yaml

from thermodrift.core import registry
from thermodrift.core.cli.run import spec_from_config
from thermodrift.core.splits import make_split
from thermodrift.testing.config_checks import compose_config

ARMS = {"dltk": ("dltk", "rbmox"), "bp": ("bp", "rbmox"), "lstm": ("lstm", "rbmox"), "cnn_lstm": ("cnn_lstm", "rbmox"),
        "ma_cnn": ("ma_cnn", "rbmox"), "cnn_lstm_transformer": ("cnn_lstm_transformer", "rbmox"),
        "tcn_lstm": ("tcn_lstm", "rbmox"), "sho_lstm": ("lstm", "sho")}


def compose(*overrides):
    return compose_config(list(overrides), registry.default().searchpaths, registry.default())


def test_the_comparison_grid_has_every_arm_under_both_protocols():
    preset = yaml.safe_load((files("thermodrift.conf") / "experiment" / "s3_rbmox_dltk.yaml").read_text())
    params = preset["hydra"]["sweeper"]["params"]  # the grid that `thermodrift run -m` expands
    assert params["+s3_arm"].split(",") == list(ARMS)
    protocols = {make_split(compose(f"split={s}").split.kind).protocol for s in params["split"].split(",")}
    assert protocols == {"honest", "paper"}


@pytest.mark.parametrize("arm", list(ARMS))
def test_each_arm_builds_its_job(arm):
    cfg = compose("experiment=s3_rbmox_dltk", f"+s3_arm={arm}", "split=s3_paper")
    spec = spec_from_config(cfg)
    assert (spec.model, spec.optimizer) == ARMS[arm]
    assert spec.dataset == "motorized_spindle_s3" and spec.selector == "hdbscan_pso"
    assert spec.split == "shuffled" and spec.split_params == {"test_fraction": 0.1}
    assert "transfer_function" in spec.baselines and "mlr" in spec.baselines
    model = registry.create("model", spec.model, **spec.model_params)  # every arm's params build its model
    assert model.trainer_settings().epochs == 20  # the preset's reduced budget
    if spec.model == "lstm":  # S3's learning-rate range and LSTM size, not S1's
        assert spec.model_search_space["trainer__lr_max"]["high"] == 0.01
        assert spec.model_search_space["hidden_units"] == {"type": "int", "low": 32, "high": 128}


def test_the_ablation_grid_tags_five_different_networks():
    seen = {}
    for tag in ("full", "no_deform", "no_lstm", "no_transformer", "no_kan"):
        cfg = compose("experiment=s3_dltk_ablation", f"+s3_ablation={tag}")
        spec = spec_from_config(cfg)
        assert cfg.ablation == tag and spec.model == "dltk" and spec.split == "condition_holdout"
        seen[tag] = tuple(spec.model_params[k] for k in ("deform", "lstm", "transformer", "kan"))
    assert len(set(seen.values())) == 5 and seen["full"] == (True, True, True, True)


@pytest.mark.parametrize("preset,extra", [("s3_rbmox_dltk", ["+s3_arm=dltk", "split=condition_holdout"]),
                                          ("s3_rbmox_dltk", ["+s3_arm=sho_lstm", "split=s3_paper"]),
                                          ("s3_rbmox_dltk", ["+s3_arm=bp", "split=s3_paper"]),
                                          ("s3_dltk_ablation", ["+s3_ablation=no_kan"])])
def test_one_override_restores_the_papers_budget(preset, extra):
    reduced = spec_from_config(compose(f"experiment={preset}", *extra))
    paper = spec_from_config(compose(f"experiment={preset}", *extra, "+s3_budget=paper"))
    epochs = [registry.create("model", s.model, **s.model_params).trainer_settings().epochs for s in (reduced, paper)]
    assert epochs == [20, 100]
    assert reduced.n_trials < 100 == paper.n_trials
    assert reduced.selector_params["n_iterations"] < 100 == paper.selector_params["n_iterations"]
    # only the budget changes: the arm's model, optimizer, search space and switches stay
    assert (paper.model, paper.optimizer, paper.model_search_space) == (reduced.model, reduced.optimizer,
                                                                        reduced.model_search_space)
    assert {k: v for k, v in paper.model_params.items() if k != "trainer"} == \
        {k: v for k, v in reduced.model_params.items() if k != "trainer"}
