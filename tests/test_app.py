"""Config composition of `thermodrift run` and its command-line handling, in-process."""

import pytest
from hydra import compose, initialize_config_module

from thermodrift.core import configs, registry
from thermodrift.core.cli.run import spec_from_config
from thermodrift.core.cli.run_options import split_flags


@pytest.fixture()
def cfg_for():
    configs.store(registry.default())  # the components' config nodes, as `thermodrift run` stores them

    def make(*overrides):
        with initialize_config_module(config_module="thermodrift.conf", version_base="1.3"):
            return compose(config_name="config", overrides=list(overrides))
    return make


def test_defaults_are_the_embedded_main_job(cfg_for):
    spec = spec_from_config(cfg_for())
    assert (spec.dataset, spec.model, spec.optimizer, spec.split) == ("demo_spindle", "transfer_function", "tpe",
                                                                  "condition_holdout")
    assert spec.baselines == ("persistence", "mlr") and spec.storage == "sqlite:///thermodrift.optuna.db"


def test_experiment_preset_overrides_top_level_keys(cfg_for):
    spec = spec_from_config(cfg_for("experiment=fl_thermal_5000rpm_heldout"))
    assert spec.dataset == "fl_thermal" and spec.targets == ["ch3(um)"]
    assert spec.split == "time_window"
    assert spec.split_params == {"train_end_h": 24.13, "test_start_h": 24.13, "test_end_h": 32.13}
    # a command-line override still wins over the preset
    overridden = spec_from_config(cfg_for("experiment=fl_thermal_5000rpm_heldout", "targets=['ch4(um)']"))
    assert overridden.targets == ["ch4(um)"]


def test_hydra_options_are_accepted_anywhere():
    flags, rest = split_flags(["model=bp", "-m", "seed=1", "--cfg", "job", "-cn", "other", "x=1"])
    assert flags == ["-m", "--cfg", "job", "-cn", "other"]
    assert rest == ["model=bp", "seed=1", "x=1"]


def test_top_level_search_space_replaces_the_models(cfg_for):
    assert spec_from_config(cfg_for("model=mlr")).model_search_space == {
        "alpha": {"type": "float", "low": 1.0e-6, "high": 100.0, "log": True}}
    assert spec_from_config(cfg_for("search_space={}")).model_search_space == {}
    narrow = spec_from_config(cfg_for("search_space={alpha: {type: float, low: 0.01, high: 10, log: true}}"))
    assert narrow.model_search_space == {"alpha": {"type": "float", "low": 0.01, "high": 10, "log": True}}
    # what the top-level key is for: Hydra merges a dict given to model.search_space into the model's
    assert set(spec_from_config(cfg_for("model=mlr", "model.search_space={}")).model_search_space) == {"alpha"}
