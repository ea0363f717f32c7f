"""The conformance suite: the contract every selector, model, optimizer, dataset, mechanism and CNC format keeps.

Built-in and third-party components run the same checks, on a tiny seeded thermal recording, in seconds.

As functions (raise :class:`ConformanceError` listing every failed check)::

    from thermodrift.testing import check_component, check_model
    check_model(MyModel)                     # a class, before it is registered
    check_component("model", "my_model")     # a registered component, including its Hydra config

As pytest classes to subclass (see :mod:`thermodrift.testing.pytest_components`, needs pytest)::

    from thermodrift.testing.pytest_components import ModelTests
    class TestMyModel(ModelTests):
        name = "my_model"

Each check is a function ``check(factory, params)`` listed by :func:`checks` (``"selector"``, ``"model"``,
``"optimizer"``, ``"dataset"``, ``"mechanism"``, ``"cnc"``); :func:`parameter_sets` gives a factory's
``get_test_params()``.
"""

from thermodrift.testing.config_checks import check_hydra_config, compose_config
from thermodrift.testing.data import tiny_frames, tiny_recording
from thermodrift.testing.suite import (
    ConformanceError,
    check_cnc_format,
    check_component,
    check_dataset,
    check_factory,
    check_mechanism,
    check_model,
    check_optimizer,
    check_selector,
    checks,
    parameter_sets,
)

__all__ = [
    "ConformanceError",
    "check_cnc_format",
    "check_component",
    "check_dataset",
    "check_factory",
    "check_mechanism",
    "check_hydra_config",
    "check_model",
    "check_optimizer",
    "check_selector",
    "checks",
    "compose_config",
    "parameter_sets",
    "tiny_frames",
    "tiny_recording",
]
