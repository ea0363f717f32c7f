"""Selector ``all``: every temperature channel (the reference that other selectors must beat)."""

from thermodrift.core.components import Selector
from thermodrift.core.hookspecs import hookimpl


class AllSensors(Selector):
    """Keep every temperature channel."""

    def _select(self, X, y):
        return list(X.columns)


@hookimpl
def thermodrift_register_selectors(registry):
    registry.add("selector", "all", AllSensors)
