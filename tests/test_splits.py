import numpy as np
import pytest

from thermodrift.core.errors import InputError
from thermodrift.core.splits import (Chronological, ConditionHoldout, ForwardChaining, Shuffled, TimeWindow,
                                     inner_fold, make_split)
from thermodrift.testing.data import tiny_recording


@pytest.fixture(scope="module")
def rec():
    return tiny_recording(seed=0)


def test_chronological_respects_time(rec):
    (fold,) = Chronological(test_fraction=0.3).folds(rec)
    t = rec.time_s
    assert t[fold.train].max() < t[fold.test].min()
    assert len(fold.test) == pytest.approx(0.3 * len(t), abs=2)
    (gapped,) = Chronological(test_fraction=0.3, gap_s=600).folds(rec)
    assert t[gapped.test].min() - t[gapped.train].max() >= 600


def test_condition_holdout_default_is_last_condition_trained_on_the_past(rec):
    labels = rec.conditions().to_numpy()
    (fold,) = ConditionHoldout().folds(rec)
    last = list(dict.fromkeys(labels))[-1]
    assert set(labels[fold.test]) == {last}
    assert last not in set(labels[fold.train])
    assert fold.train.max() < fold.test.min()


def test_condition_holdout_by_substring_and_others(rec):
    labels = rec.conditions().to_numpy()
    (before,) = ConditionHoldout(test_conditions=["4000rpm"]).folds(rec)
    assert all("4000rpm" in lab for lab in labels[before.test])
    assert before.train.max() < before.test.min()
    (others,) = ConditionHoldout(test_conditions=["4000rpm"], train_on="others").folds(rec)
    assert len(others.train) > len(before.train)
    assert not set(others.train) & set(others.test)
    with pytest.raises(InputError, match="match none"):
        ConditionHoldout(test_conditions=["9999rpm"]).folds(rec)


def test_condition_holdout_train_end_limits_the_training_rows(rec):
    labels = rec.conditions().to_numpy()
    h = (rec.time_s - rec.time_s[0]) / 3600
    (others,) = ConditionHoldout(test_conditions=["4000rpm"], train_on="others").folds(rec)
    end = float(h[others.test].max()) + 0.5  # some conditions after the held-out one stay, later ones go
    (limited,) = ConditionHoldout(test_conditions=["4000rpm"], train_on="others", train_end_h=end).folds(rec)
    assert h[limited.train].max() < end and np.array_equal(limited.test, others.test)
    assert set(limited.train) < set(others.train) and h[limited.train].max() > h[limited.test].max()
    assert not set(labels[limited.train]) & set(labels[limited.test])
    with pytest.raises(InputError, match="no training rows"):
        ConditionHoldout(test_conditions=[labels[0]], train_end_h=h[-1]).folds(rec)
    with pytest.raises(InputError, match="train_end_h"):
        ConditionHoldout(train_end_h=0)


def test_time_window(rec):
    (fold,) = TimeWindow(train_end_h=2.0, test_start_h=2.5, test_end_h=4.0).folds(rec)
    h = rec.time_s / 3600
    assert h[fold.train].max() < 2.0 and h[fold.test].min() >= 2.5 and h[fold.test].max() < 4.0


def test_forward_chaining_expands(rec):
    folds = ForwardChaining(min_train_conditions=2).folds(rec)
    assert len(folds) == len(set(rec.conditions())) - 2
    sizes = [len(f.train) for f in folds]
    assert sizes == sorted(sizes) and len(set(sizes)) == len(sizes)
    for f in folds:
        assert f.train.max() < f.test.min()


def test_shuffled_is_labelled_and_warns(rec):
    split = Shuffled(test_fraction=0.2, seed=1)
    assert split.protocol == "paper"
    with pytest.warns(UserWarning, match="paper protocol"):
        (fold,) = split.folds(rec)
    assert np.array_equal(fold.test, Shuffled(test_fraction=0.2, seed=1).folds(rec)[0].test)
    assert fold.train.max() > fold.test.min()  # interleaved in time: the leak the label warns about


def test_inner_fold_holds_out_last_training_condition(rec):
    (outer,) = ConditionHoldout().folds(rec)
    train = rec.select(outer.train)
    inner = inner_fold(train)
    labels = train.conditions().to_numpy()
    assert len(set(labels[inner.test])) == 1 and inner.train.max() < inner.test.min()


def test_make_split_rejects_unknown():
    with pytest.raises(InputError, match="unknown split"):
        make_split("random_rows")


def test_inner_fold_ignores_a_sliver_of_the_next_condition(rec):
    labels = rec.conditions().to_numpy()
    order = list(dict.fromkeys(labels))
    first_of_last = int(np.flatnonzero(labels == order[-1])[0])
    part = rec.select(np.arange(first_of_last + 2))  # a time cut that keeps 2 samples of the last block
    inner = inner_fold(part)
    part_labels = part.conditions().to_numpy()
    assert set(part_labels[inner.test]) == {order[-2]}
    assert order[-1] not in set(part_labels[inner.train]) and len(inner.test) > 2

