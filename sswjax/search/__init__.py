"""Gradient-based (optax) search of the traced parameters, through a soft-argmin relaxation of
the inference graph.

===============  ===============================================================================
``space``        the search space, read from the options' declarations: raw keys, transforms
                 (simplex, sigmoid, softplus), the differentiable stand-ins of static options
``objective``    soft-argmin of the inference volume (``graph.volume``) and the smooth-L1 loss
``step``         the optax optimiser with frozen keys; the jitted update step, sharded over
                 devices
``crops``        the loss's pixels, random fixed-size crops, prepared scenes, data-set folds
``checkpoints``  atomic save and load of a search's state
===============  ===============================================================================

The driver (folds, evaluation, resumable runs) is ``tuning/search.py``.
"""

from sswjax.search.checkpoints import load_checkpoint, save_checkpoint
from sswjax.search.crops import (MAX_CROP_TRIES, crop_segments, dataset_folds, prepare_scene,
                                 random_crops, valid_mask)
from sswjax.search.objective import HUBER_DELTA, batch_loss, loss, smooth_l1, soft_disparity
from sswjax.search.space import (MIN_TEMPERATURE, SEARCHED, SGM_SEARCHED, TEMPERATURE,
                                 all_raw_keys, differentiable, from_unconstrained, raw_keys,
                                 raw_to_params, searchable, searched_fields, to_unconstrained,
                                 value_of)
from sswjax.search.step import freeze_labels, make_optimizer, make_update_step, shard_crops

__all__ = [
    "HUBER_DELTA", "MAX_CROP_TRIES", "MIN_TEMPERATURE", "SEARCHED", "SGM_SEARCHED",
    "TEMPERATURE", "all_raw_keys", "batch_loss", "crop_segments", "dataset_folds",
    "differentiable", "freeze_labels", "from_unconstrained", "load_checkpoint", "loss",
    "make_optimizer", "make_update_step", "prepare_scene", "random_crops", "raw_keys",
    "raw_to_params", "save_checkpoint", "searchable", "searched_fields", "shard_crops",
    "smooth_l1", "soft_disparity", "to_unconstrained", "valid_mask", "value_of",
]
