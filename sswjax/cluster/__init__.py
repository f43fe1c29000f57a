"""Beyond one process: Dask distributed as the engine, for many pairs and for many tiles.

==========  ===================================================================================
``workers`` starting or joining a cluster; the workers spawned, each on a core of its own,
            the compilation cache they share (``pip install "sswjax[distributed]"``)
``cores``   a process pinned to one core (XLA's pool follows), the workers' cores per host
``tasks``   what runs in a worker: one pair of a folder (read, match, write), one tile's window
``folders`` ``match_pairs``, ``match_folder``: pairs as tasks, their outcomes as they arrive
``engine``  ``DaskEngine``, ``match_tiles``: one pair's tiles as tasks, stitched
``pairs``   the pairs of two folders, their sizes from the headers
==========  ===================================================================================

``docs/cluster.md`` tells how to run on a cluster and how far the design goes.
"""

from sswjax.cluster.engine import DaskEngine, match_tiles
from sswjax.cluster.folders import FolderSummary, match_folder, match_pairs
from sswjax.cluster.tasks import PairJob, PairOutcome
from sswjax.cluster.workers import (
           connect,
           local_cluster,
           pin_workers,
           worker_environment,
)

__all__ = ["DaskEngine", "FolderSummary", "PairJob", "PairOutcome", "connect", "local_cluster",
           "match_folder", "match_pairs", "match_tiles", "pin_workers", "worker_environment"]
