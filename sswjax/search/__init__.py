"""Gradient-based (optax) search of the traced parameters, through a soft-argmin relaxation of
the inference graph.

===============  ===============================================================================
``space``        the search space, read from the options' declarations: raw keys, transforms
                 (simplex, sigmoid, softplus), the differentiable stand-ins of static options
``objective``    the inference volume (``graph.volume``), its soft-argmin, the loss of a crop
``surrogates``   the differentiable stand-ins of the bad-pixel rate, registered by name
``step``         the optax optimiser with frozen keys; the jitted update step, sharded over
                 devices
``crops``        the loss's pixels, random fixed-size crops, prepared scenes, data-set folds
``checkpoints``  atomic save and load of a search's state
``settings``     :class:`SearchSettings`: steps, batches, crops, surrogate, validation, restarts
``run``          the search loop: crops, Adam, validation on whole images, early stopping,
                 restarts, resumable starts
``held_out``     a run with its held-out report (leave one data set or one scene out) and the
                 final search on everything; what ``sswjax search`` runs
===============  ===============================================================================

The earlier driver (``tuning/search.py``) left the tree, superseded by ``sswjax search``; it
is in git history (``docs/notes/benchmarks-concluded.md``), and the tables recorded with it stay
in ``tuning/README.md``.
"""

from sswjax.search.checkpoints import load_checkpoint, save_checkpoint
from sswjax.search.held_out import FOLD_MODES, folds, report_markdown, search_with_report
from sswjax.search.crops import (MAX_CROP_TRIES, crop_segments, dataset_folds, prepare_scene,
                                 random_crops, valid_mask)
from sswjax.search.objective import batch_loss, loss, search_volume, soft_disparity
from sswjax.search.space import (MIN_TEMPERATURE, SEARCHED, SGM_SEARCHED, TEMPERATURE,
                                 all_raw_keys, differentiable, from_unconstrained, raw_keys,
                                 raw_to_params, searchable, searched_fields, to_unconstrained,
                                 value_of)
from sswjax.search.run import SearchResult, run_search, searched_options, validation_error
from sswjax.search.settings import SearchSettings
from sswjax.search.step import freeze_labels, make_optimizer, make_update_step, shard_crops
from sswjax.search.surrogates import (DEFAULT_SURROGATE, HUBER_DELTA, SURROGATES, smooth_l1,
                                      surrogate)

__all__ = [
    "DEFAULT_SURROGATE", "FOLD_MODES", "HUBER_DELTA", "MAX_CROP_TRIES", "MIN_TEMPERATURE",
    "SEARCHED", "SGM_SEARCHED", "SURROGATES", "TEMPERATURE", "all_raw_keys", "batch_loss",
    "crop_segments", "dataset_folds", "differentiable", "folds", "freeze_labels",
    "from_unconstrained", "load_checkpoint", "loss", "make_optimizer", "make_update_step",
    "prepare_scene", "random_crops", "raw_keys", "raw_to_params", "report_markdown",
    "run_search", "save_checkpoint", "search_volume", "search_with_report", "searchable",
    "searched_fields", "searched_options", "SearchResult", "SearchSettings", "shard_crops",
    "smooth_l1", "soft_disparity", "surrogate", "to_unconstrained", "valid_mask",
    "validation_error", "value_of",
]
