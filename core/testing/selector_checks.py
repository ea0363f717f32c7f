"""Contract checks for selectors (``thermodrift.core.components.Selector``), run on the tiny recording."""

from __future__ import annotations

import pandas as pd

from thermodrift.testing.data import tiny_frames
from thermodrift.testing.estimator_checks import SHARED_CHECKS, Factory, fitted_attributes, pickled, seeded


def _fitted(factory: Factory, params: dict):
    X, y = tiny_frames()
    return seeded(factory(**params)).fit(X, y), X, y


def check_selects_subset(factory: Factory, params: dict) -> None:
    """``fit`` returns self and sets ``selected_``, distinct input columns (at least one); ``transform`` keeps them."""
    X, y = tiny_frames()
    sel = seeded(factory(**params))
    assert sel.fit(X, y) is sel, "fit() must return self"
    chosen = getattr(sel, "selected_", None)
    assert isinstance(chosen, list) and chosen, f"selected_ must be a non-empty list of column names, got {chosen!r}"
    assert len(set(chosen)) == len(chosen), f"selected_ repeats columns: {chosen}"
    unknown = [c for c in chosen if c not in X.columns]
    assert not unknown, f"selected_ names columns that are not in the input: {unknown}"
    out = sel.transform(X)
    assert isinstance(out, pd.DataFrame) and list(out.columns) == chosen and out.index.equals(X.index), (
        "transform(X) must return X[selected_] with the same index")


def check_selection_deterministic(factory: Factory, params: dict) -> None:
    """Two fits with the same parameters (``random_state=0`` where there is one) select the same columns."""
    first = _fitted(factory, params)[0].selected_
    second = _fitted(factory, params)[0].selected_
    assert first == second, f"two fits with the same seed selected {first} and then {second}"


def check_selection_idempotent(factory: Factory, params: dict) -> None:
    """Fitting again on only the selected columns keeps all of them."""
    sel, X, y = _fitted(factory, params)
    again = seeded(factory(**params)).fit(X[sel.selected_], y).selected_
    assert set(again) == set(sel.selected_), (
        f"refitting on the selected columns {sel.selected_} selected {again}; a selection must be stable")


def check_selector_pickle(factory: Factory, params: dict) -> None:
    """A fitted selector survives pickling with the same selection."""
    sel, X, _ = _fitted(factory, params)
    copy = pickled(sel)
    assert copy.selected_ == sel.selected_, "selected_ changed after a pickle round trip"
    pd.testing.assert_frame_equal(copy.transform(X), sel.transform(X))
    assert fitted_attributes(copy) == fitted_attributes(sel), "fitted attributes lost in a pickle round trip"


SELECTOR_CHECKS = (*SHARED_CHECKS, check_selects_subset, check_selection_deterministic, check_selection_idempotent,
                   check_selector_pickle)
