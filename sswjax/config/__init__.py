"""The parameters of the method: one small configuration per stage, composed into ``Params``.

=================  ==============================================================================
``fields``         ``option(...)``: an option static or traced, its bounds, choices and search
                   transform; ``stage_config`` makes a class a frozen dataclass and a pytree
``parts``          the slots (the stages, in pipeline order) and the registry of their parts
``alignment``      the rectification's residual vertical offset, measured and taken out
``preprocess``     what the matching cost sees of the images (local contrast normalisation)
``cost``           the matching cost (Eq. 1-5)
``segments``       the superpixels (Eq. 6)
``aggregation``    the segment-side-window aggregation (Eq. 7) and the baseline aggregators
``optimizer``      semi-global optimisation (full and half resolution)
``selection``      winner-takes-all and its sub-pixel fit (Eq. 8)
``checks``         the tests that reject pixels: left-right (Eq. 9), uniqueness, aggregated view
``fill``           the fills of the rejected pixels, one class each
``refinement``     the side-window median over the map
``coarse``         coarse-to-fine: the pair halved, the map doubled back
``band``           the full-resolution search of a few disparities around the map before it
``smoothing``      the edge-aware smoothing of the finished map
``params``         ``Params``, the root; ``replace`` by stage (a configuration, a kind, options)
                   or dotted option
``validate``       checks derived from the options' declarations; rules across stages
``serialize``      nested JSON (old flat files are refused, naming ``sswjax params --upgrade``)
``presets``        the named compositions and the default
=================  ==============================================================================
"""

from sswjax.config.aggregation import (Aggregator, BilateralAggregation, BoxAggregation,
                                       GuidedAggregation, IteratedGuidedAggregation,
                                       MedianAggregation, SideWindowAggregation)
from sswjax.config.alignment import VerticalAlignment
from sswjax.config.band import DisparityBand
from sswjax.config.checks import LeftRightCheck
from sswjax.config.coarse import CoarseToFine
from sswjax.config.cost import MatchingCost
from sswjax.config.fields import ConfigError, Option, option, stage_config
from sswjax.config.fill import (BackgroundFill, Fill, LeftBandFill, PlaneFill, VoteFill,
                                WeightedMedianFill)
from sswjax.config.optimizer import HalfResolutionSemiGlobal, Optimizer, SemiGlobal
from sswjax.config.params import Params
from sswjax.config.parts import SLOTS, Part, kinds, register
from sswjax.config.presets import DEFAULT_PRESET, PRESETS, default_params, preset
from sswjax.config.preprocess import LocalContrast, Preprocessor
from sswjax.config.refinement import SideWindowMedian
from sswjax.config.segments import Slic
from sswjax.config.selection import WinnerTakesAll
from sswjax.config.serialize import load_params, params_from_dict, save_params
from sswjax.config.smoothing import GatedBilateralSmoothing
from sswjax.config.validate import check_params

__all__ = [
    "Aggregator", "BackgroundFill", "BilateralAggregation", "BoxAggregation", "CoarseToFine",
    "ConfigError", "DEFAULT_PRESET", "DisparityBand", "Fill", "GatedBilateralSmoothing", "GuidedAggregation", "HalfResolutionSemiGlobal",
    "IteratedGuidedAggregation", "LeftBandFill", "LeftRightCheck", "LocalContrast",
    "MatchingCost", "MedianAggregation", "Optimizer", "Option", "PRESETS", "Params", "Part",
    "PlaneFill", "Preprocessor", "SLOTS", "SemiGlobal", "SideWindowAggregation",
    "SideWindowMedian", "Slic", "VerticalAlignment", "VoteFill", "WeightedMedianFill", "WinnerTakesAll",
    "check_params", "default_params", "kinds", "load_params", "option", "params_from_dict",
    "preset", "register", "save_params", "stage_config",
]
