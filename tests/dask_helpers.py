"""A LocalCluster for the tests."""

import contextlib


@contextlib.contextmanager
def local_cluster(workers: int = 2):
    """(cluster, client): a LocalCluster of ``workers`` single-threaded worker processes
    and its client, both closed on leaving. The dashboard takes a free port: at the
    default one, a cluster the other test worker runs at that moment makes Dask warn
    (an error here) and the cluster fail to start."""
    from dask.distributed import Client, LocalCluster

    with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                      dashboard_address=":0") as cluster, Client(cluster) as client:
        yield cluster, client
