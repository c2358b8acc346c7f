"""Cross-validation on sequences: SequenceSplit, the sample_index checks, metadata routing."""

import warnings

import numpy as np
import pysindy as ps
import pytest
import sklearn
from sklearn.base import clone
from sklearn.model_selection import GridSearchCV, KFold, TimeSeriesSplit, cross_val_score
from sklearn.pipeline import Pipeline
from sklearn.preprocessing import FunctionTransformer

from sk_offwhite import GreyBoxSparseRegressor, SequenceSplit, SequenceWarning
from sk_offwhite.datasets import make_leaky_tank

N_SAMPLES = 240


@pytest.fixture(scope="module")
def tank():
    data = make_leaky_tank(n_samples=N_SAMPLES, random_state=0)
    return data.u, data.z


def linear(**params):
    return GreyBoxSparseRegressor(None, **{"max_iter": 20, **params})


def runs(index: np.ndarray) -> list[np.ndarray]:
    """``index`` cut into runs of consecutive integers."""
    return np.split(index, np.flatnonzero(np.diff(index) != 1) + 1)


def explicit_scores(est, u, z, cv, grid: dict) -> dict:
    """Per parameter value, the held-out score of every fold, each fit told its rows."""
    scores = {}
    for value in next(iter(grid.values())):
        params = {next(iter(grid)): value}
        scores[value] = [
            clone(est)
            .set_params(**params)
            .fit(u[train], z[train], sample_index=train)
            .score(u[test], z[test], sample_index=test)
            for train, test in cv.split(u)
        ]
    return scores


def search_scores(search) -> dict:
    results, n_splits = search.cv_results_, search.n_splits_
    return {
        next(iter(params.values())): [results[f"split{k}_test_score"][i] for k in range(n_splits)]
        for i, params in enumerate(results["params"])
    }


# ---------------------------------------------------------------------- the folds
@pytest.mark.parametrize("train", ["longer", "rest", "forward"])
@pytest.mark.parametrize("n_samples, n_splits, gap", [(9, 3, 0), (101, 4, 0), (101, 4, 3)])
def test_folds_are_contiguous_blocks(train, n_samples, n_splits, gap):
    folds = list(SequenceSplit(n_splits, train=train, gap=gap).split(np.zeros((n_samples, 1))))
    assert len(folds) == n_splits
    tests = np.concatenate([test for _, test in folds])
    first = 0 if train != "forward" else n_samples - n_splits * (n_samples // (n_splits + 1))
    np.testing.assert_array_equal(tests, np.arange(first, n_samples))  # each row tested once
    for train_rows, test in folds:
        assert len(runs(test)) == 1
        assert len(runs(train_rows)) == 1 or (train == "rest" and len(runs(train_rows)) == 2)
        if train == "rest" and gap == 0:
            np.testing.assert_array_equal(np.sort(np.r_[train_rows, test]), np.arange(n_samples))
        distance = np.abs(train_rows[:, None] - test[None, :]).min()
        assert distance == gap + 1
        if train == "forward":
            assert train_rows.max() < test.min()


def test_longer_trains_on_the_longer_side_of_the_test_block():
    folds = list(SequenceSplit(5).split(np.zeros((50, 1))))
    lengths = [len(train) for train, _ in folds]
    assert lengths == [40, 30, 20, 30, 40]
    assert folds[2][0].max() < folds[2][1].min()  # a tie trains on the earlier side


def test_rest_gives_the_folds_of_unshuffled_kfold():
    X = np.zeros((103, 1))
    for ours, theirs in zip(
        SequenceSplit(4, train="rest").split(X), KFold(4).split(X), strict=True
    ):
        np.testing.assert_array_equal(ours[0], theirs[0])
        np.testing.assert_array_equal(ours[1], theirs[1])


@pytest.mark.parametrize("gap", [0, 2])
def test_forward_gives_the_folds_of_time_series_split(gap):
    X = np.zeros((103, 1))
    ours = SequenceSplit(4, train="forward", gap=gap).split(X)
    for (train, test), (train_ts, test_ts) in zip(
        ours, TimeSeriesSplit(4, gap=gap).split(X), strict=True
    ):
        np.testing.assert_array_equal(train, train_ts)
        np.testing.assert_array_equal(test, test_ts)


def test_repr_and_number_of_splits():
    cv = SequenceSplit(4, train="rest", gap=1)
    assert repr(cv) == "SequenceSplit(gap=1, n_splits=4, test_size=None, train='rest')"
    assert cv.get_n_splits() == 4


@pytest.mark.parametrize(
    "params, name",
    [
        ({"n_splits": 1}, "n_splits"),
        ({"n_splits": 2.5}, "n_splits"),
        ({"n_splits": True}, "n_splits"),
        ({"train": "shuffled"}, "train"),
        ({"gap": -1}, "gap"),
        ({"gap": True}, "gap"),
    ],
)
def test_invalid_parameters_name_the_argument(params, name):
    with pytest.raises(ValueError, match=f"'{name}' parameter of SequenceSplit"):
        SequenceSplit(**params)


@pytest.mark.parametrize(
    "cv, n_samples, match",
    [
        (SequenceSplit(5), 9, "n_splits=5 cuts 9 samples into 5 blocks"),
        (SequenceSplit(3, gap=2), 9, "fold 1 a training run of 1 row"),
        (SequenceSplit(3, train="rest", gap=2), 9, "fold 1 a training run of 1 row"),
    ],
)
def test_too_little_data_for_the_folds_is_an_error(cv, n_samples, match):
    with pytest.raises(ValueError, match=match):
        list(cv.split(np.zeros((n_samples, 1))))


# ---------------------------------------------------------------------- searches
def test_grid_search_without_sample_index_matches_the_explicit_protocol(tank):
    """No sample_index given: each fold's fit still sees one contiguous record."""
    u, z = tank
    est = GreyBoxSparseRegressor(None, library=ps.PolynomialLibrary(degree=1), max_iter=10)
    grid = {"gamma": [1e-4, 1.0]}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # ConvergenceWarning of the short fits
        search = GridSearchCV(est, grid, cv=SequenceSplit(3), refit=False).fit(u, z)
        expected = explicit_scores(est, u, z, SequenceSplit(3), grid)
    for gamma, scores in search_scores(search).items():
        np.testing.assert_allclose(scores, expected[gamma], rtol=1e-8)
    assert not np.allclose(expected[1e-4], expected[1.0])  # gamma matters here
    best = max(expected, key=lambda gamma: np.mean(expected[gamma]))
    assert search.best_params_["gamma"] == best


def test_cross_val_score_with_the_default_splitter(tank):
    u, z = tank
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sklearn.exceptions.ConvergenceWarning)
        scores = cross_val_score(linear(), u, z, cv=SequenceSplit(3))
    assert scores.shape == (3,) and scores.min() > 0.9


# ---------------------------------------------------------------------- sample_index
def test_shuffled_folds_warn_in_fit_and_score(tank):
    u, z = tank
    train, test = next(KFold(3, shuffle=True, random_state=0).split(u))
    est = linear(max_iter=2)
    with pytest.warns(SequenceWarning, match="single row.*SequenceSplit"):
        est.fit(u[train], z[train], sample_index=train)
    with pytest.warns(SequenceWarning, match="Shuffled folds"):
        est.score(u[test], z[test], sample_index=test)


def test_blocks_in_any_order_do_not_warn(tank):
    u, z = tank
    keep, swapped = np.r_[0:100, 140:240], np.r_[140:240, 0:100]
    with warnings.catch_warnings():
        warnings.simplefilter("error", SequenceWarning)
        est = linear(max_iter=2).fit(u[keep], z[keep], sample_index=keep)
        est.score(u[swapped], z[swapped], sample_index=swapped)


@pytest.mark.parametrize(
    "sample_index",
    [
        np.r_[np.arange(59), np.nan],
        np.arange(60) + 0.5,
        np.array([str(i) for i in range(60)]),
        np.ones(60, bool),
        np.arange(60).astype("datetime64[s]"),
    ],
    ids=["nan", "fraction", "strings", "booleans", "dates"],
)
def test_non_integer_sample_index_is_an_error(tank, sample_index):
    u, z = tank
    with pytest.raises(ValueError, match="sample_index must hold the integer position"):
        linear().fit(u[:60], z[:60], sample_index=sample_index)


def test_integral_float_sample_index_is_the_integer_one(tank):
    u, z = tank
    keep = np.r_[0:30, 40:70]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sklearn.exceptions.ConvergenceWarning)
        as_int = linear().fit(u[keep], z[keep], sample_index=keep)
        as_float = linear().fit(u[keep], z[keep], sample_index=keep.astype(float))
    np.testing.assert_array_equal(as_int.initial_states_, as_float.initial_states_)
    assert as_int.initial_states_.shape[0] == 2


def test_score_weights_the_scored_samples(tank):
    """Zero weights on the second record score the first one alone."""
    u, z = tank
    keep = np.r_[0:100, 140:240]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sklearn.exceptions.ConvergenceWarning)
        est = linear().fit(u, z)
    weights = np.r_[np.ones(100), np.zeros(100)]
    weighted = est.score(u[keep], z[keep], sample_index=keep, sample_weight=weights)
    assert weighted == pytest.approx(est.score(u[:100], z[:100]), rel=1e-12)
    with pytest.raises(ValueError, match="sample_weight"):
        est.score(u, z, sample_weight=np.ones(3))


# ---------------------------------------------------------------------- metadata routing
def test_only_sample_index_is_routable_metadata():
    routing = GreyBoxSparseRegressor().get_metadata_routing()
    assert set(routing.fit.requests) == {"sample_index"}
    assert set(routing.score.requests) == {"sample_index", "sample_weight"}
    assert "u" not in routing.predict.requests


def test_the_baseline_routes_only_sample_index():
    from sk_offwhite.baselines import DelaySINDyRegressor

    with sklearn.config_context(enable_metadata_routing=True):
        baseline = clone(DelaySINDyRegressor().set_fit_request(sample_index=True))
        assert baseline.get_metadata_routing().fit.requests == {"sample_index": True}


def test_clone_keeps_the_metadata_requests():
    with sklearn.config_context(enable_metadata_routing=True):
        est = GreyBoxSparseRegressor(gamma=0.5).set_fit_request(sample_index=True)
        est.set_score_request(sample_index="time")
        copy = clone(est)
        assert copy.get_metadata_routing().fit.requests == {"sample_index": True}
        assert copy.get_metadata_routing().score.requests["sample_index"] == "time"
        assert copy.gamma == 0.5


def test_grid_search_over_a_pipeline_routes_sample_index(tank):
    """Metadata routing on: the two runs of each training fold reach fit as two records."""
    u, z = tank
    cv = SequenceSplit(3, train="rest")
    grid = {"max_iter": [5, 20]}
    with sklearn.config_context(enable_metadata_routing=True), warnings.catch_warnings():
        warnings.simplefilter("ignore", sklearn.exceptions.ConvergenceWarning)
        est = linear().set_fit_request(sample_index=True).set_score_request(sample_index=True)
        pipe = Pipeline([("identity", FunctionTransformer()), ("model", est)])
        search = GridSearchCV(pipe, {"model__max_iter": grid["max_iter"]}, cv=cv, n_jobs=1)
        search.fit(u, z, sample_index=np.arange(len(u)))
        expected = explicit_scores(linear(), u, z, cv, grid)
    for max_iter, scores in search_scores(search).items():
        np.testing.assert_allclose(scores, expected[max_iter], rtol=1e-8)
