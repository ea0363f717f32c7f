"""Model ``persistence``: predicts the previous measured displacement (µm).

A reference, not a compensation model: it reads the target's own last sample, which a machine in production does
not measure. A learned model that cannot beat it on a held-out condition has learned little.
"""

from thermodrift.core.components import LAG_PREFIX, ThermalModel
from thermodrift.core.hookspecs import hookimpl


class Persistence(ThermalModel):
    """ŷ(t) = y(t − 1 sample), read from the ``lag1:<channel>`` columns the study adds (µm)."""

    uses_target_history = True

    def _fit(self, X, y):
        self.lag_columns_ = [c for c in X.columns if str(c).startswith(LAG_PREFIX)]
        if len(self.lag_columns_) != y.shape[1]:
            raise ValueError(f"persistence needs one '{LAG_PREFIX}<channel>' column per target, "
                             f"got {self.lag_columns_}")

    def _predict(self, X):
        return X[self.lag_columns_].to_numpy(dtype=float)


@hookimpl
def thermodrift_register_models(registry):
    registry.add("model", "persistence", Persistence)
