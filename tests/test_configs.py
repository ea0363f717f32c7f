"""The code is the one home of a component's defaults: configs are generated from the class (core/configs.py), and
a shipped YAML is a preset that differs from what the registry would generate."""

import pytest
from omegaconf import OmegaConf

from thermodrift.core import configs, registry
from thermodrift.core.cli.run import spec_from_config
from thermodrift.core.registry import CONFIG_GROUPS, Registry
from thermodrift.testing import compose_config


def test_no_shipped_yaml_repeats_what_the_registry_generates():
    assert configs.repeated_yamls(registry.default()) == []


def test_the_check_finds_a_restating_yaml_and_spares_a_preset(tmp_path):
    reg = registry.load()
    (tmp_path / "model").mkdir()
    (tmp_path / "optimizer").mkdir()
    (tmp_path / "model" / "mnr.yaml").write_text("name: mnr\nparams:\n  degree: 2\n")  # a subset of the defaults
    (tmp_path / "optimizer" / "gwo_big.yaml").write_text("name: gwo\nparams:\n  population_size: 40\n")  # a preset
    (tmp_path / "optimizer" / "gwo_again.yaml").write_text("name: gwo\nparams:\n  population_size: 10\n")
    assert configs.repeated_yamls(reg, [f"file://{tmp_path}"]) == ["model/mnr.yaml", "optimizer/gwo_again.yaml"]


@pytest.mark.parametrize("kind", list(CONFIG_GROUPS))
def test_every_built_in_component_composes_with_the_defaults_of_its_class(kind):
    """Without a YAML the composed ``params`` are the constructor's defaults: a default changed in Python reaches
    ``thermodrift run``."""
    reg = registry.default()
    group = CONFIG_GROUPS[kind]
    shipped = configs.yaml_files(reg.searchpaths, group)
    names = [n for n in reg.names(kind) if n not in shipped and reg.get(kind, n).origin == "thermodrift"]
    assert names, f"no built-in {kind} composes from its class"
    for name in names:
        cfg = compose_config([f"{group}={name}"] + _required(kind, name), reg.searchpaths, reg)
        composed = OmegaConf.to_container(cfg[group], resolve=False)
        expected = configs.node(reg.get(kind, name))
        expected["params"].update({k: composed["params"][k] for k, v in expected["params"].items() if v == "???"})
        assert composed == expected, name


def _required(kind: str, name: str) -> list[str]:
    node = configs.node(registry.default().get(kind, name))
    return [f"{CONFIG_GROUPS[kind]}.params.{k}=x" for k, v in node["params"].items() if v == "???"]


def test_a_changed_python_default_reaches_the_composed_config(monkeypatch):
    reg = registry.load()
    cls = reg.get("model", "mnr").factory
    original = cls.__init__

    def changed(self, degree: int = 3, alpha: float = 1.0):
        original(self, degree=degree, alpha=alpha)

    monkeypatch.setattr(cls, "__init__", changed)
    spec = spec_from_config(compose_config(["model=mnr"], reg.searchpaths, reg))
    assert spec.model_params["degree"] == 3
    monkeypatch.undo()
    configs.store(reg)  # the process-wide ConfigStore gets the class's real defaults back


def test_the_run_seed_reaches_components_whose_config_is_generated():
    """A generated node leaves out the seed the job passes, so ``seed=`` seeds the model and the selector."""
    reg = Registry()
    reg.add("model", "seeded_linear", SeededLinear)
    assert "random_state" not in configs.node(reg.get("model", "seeded_linear"))["params"]
    reg = registry.default()
    spec = spec_from_config(compose_config(["model=lstm", "selector=random_k", "seed=7"], reg.searchpaths, reg))
    assert "random_state" not in spec.model_params and "random_state" not in spec.selector_params
    assert registry.with_seed(reg.get("model", "lstm").factory, spec.model_params, spec.seed)["random_state"] == 7
    assert registry.with_seed(reg.get("selector", "random_k").factory, spec.selector_params, spec.seed)["random_state"] == 7


class SeededLinear:
    def __init__(self, alpha: float = 1.0, random_state: int = 0):
        self.alpha, self.random_state = alpha, random_state


def test_a_parameter_without_default_must_be_given_on_the_command_line():
    reg = Registry()

    def table_reader(table: str, sep: str = ","):
        return None

    reg.add("dataset", "table_reader", table_reader)
    assert configs.node(reg.get("dataset", "table_reader"))["params"] == {"table": "???", "sep": ","}
    cfg = compose_config(["dataset=table_reader"], [], reg)
    with pytest.raises(Exception, match=r"dataset\.params\.table has no value: add dataset\.params\.table=<value>"):
        spec_from_config(cfg)


def test_a_torch_models_trainer_settings_are_all_overridable():
    """Every trainer field is in the generated node, so `model.params.trainer.<field>=` works for every model
    (a shipped YAML with a subset hid the rest)."""
    reg = registry.default()
    spec = spec_from_config(compose_config(["model=pso_bpnn", "model.params.trainer.loss=mae"], reg.searchpaths, reg))
    assert spec.model_params["trainer"]["loss"] == "mae"
