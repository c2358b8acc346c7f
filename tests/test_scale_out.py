"""GridSearchCV of the estimator through joblib on Dask and Ray matches the local result.

The Dask test runs in CI (the ``dask`` extra); the Ray test runs where the ``ray`` extra is
installed and is skipped otherwise.
"""

import numpy as np
import pytest
from sklearn.model_selection import GridSearchCV, KFold

from sk_offwhite import GreyBoxSparseRegressor
from sk_offwhite.datasets import cascaded_tanks_physics, make_cascaded_tanks

joblib = pytest.importorskip("joblib")

GAMMAS = [1e-4, 1e-2]


def _search():
    data = make_cascaded_tanks(
        n_samples=160, overflow=False, saturation=False, noise_std=0.01, random_state=0
    )
    physics = cascaded_tanks_physics(fixed={"k4": data.true_parameters["k4"]})
    est = GreyBoxSparseRegressor(physics, max_iter=20, init_window=0)  # no x0 estimation to compile
    search = GridSearchCV(est, {"gamma": GAMMAS}, cv=KFold(2))
    return search, data.u, data.z


def _fit(search, u, z):
    return search.fit(u, z, sample_index=np.arange(len(u)))


def _assert_same_search(remote, local):
    assert remote.best_params_ == local.best_params_
    np.testing.assert_allclose(
        remote.cv_results_["mean_test_score"], local.cv_results_["mean_test_score"], rtol=1e-8
    )


@pytest.mark.filterwarnings("ignore::sklearn.exceptions.ConvergenceWarning")
def test_grid_search_on_local_dask_cluster_matches_local_run():
    distributed = pytest.importorskip("dask.distributed")
    local = _fit(*_search())
    cluster = distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
        dashboard_address=None,
    )  # fmt: skip
    with cluster, distributed.Client(cluster) as client:
        search, u, z = _search()
        with joblib.parallel_backend("dask"), distributed.get_task_stream(client) as stream:
            remote = _fit(search, u, z)
        n_threads = client.nthreads()  # asks the scheduler; scheduler_info() may be a stale cache
    assert len(n_threads) == 2
    assert len(stream.data) >= len(GAMMAS) * 2  # every (gamma, fold) fit ran on the cluster
    _assert_same_search(remote, local)


@pytest.mark.filterwarnings("ignore::sklearn.exceptions.ConvergenceWarning")
@pytest.mark.filterwarnings("ignore::DeprecationWarning")
def test_grid_search_on_local_ray_matches_local_run():
    ray = pytest.importorskip("ray")
    ray_joblib = pytest.importorskip("ray.util.joblib")
    local = _fit(*_search())
    ray.init(num_cpus=2, include_dashboard=False)
    try:
        ray_joblib.register_ray()
        search, u, z = _search()
        with joblib.parallel_backend("ray"):
            remote = _fit(search, u, z)
        n_cpus = ray.cluster_resources()["CPU"]
    finally:
        ray.shutdown()
    assert n_cpus == 2
    _assert_same_search(remote, local)
