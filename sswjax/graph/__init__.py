"""The jitted graph: the stages composed into the method, for one pair of JAX arrays.

=============  ==================================================================================
``scopes``     the stage names of the compiled graph (``jax.named_scope``), an enum
``padding``    a pair padded to a shape bucket matched as at its own size (traced ``valid_shape``)
``volume``     the scene a call shares; the volume built in blocks, optimised, folded into winners
``refine``     sub-pixel fit, the checks, the fill, the median (Eq. 8-9)
``coarse``     coarse-to-fine: the method on the pair halved, the map doubled back
``match``      the jitted entry points: ``ssw_disparity``, ``ssw_outputs``, ``ssw_cues``; for a
               window of row strips whose paths are carried, ``ssw_carried`` (the states it
               leaves) and ``ssw_disparity_seeded``, ``ssw_outputs_seeded`` (its maps too)
``alignment``  ``align_right``, the vertical alignment: the jitted step before the method
               (``ssw_aligned``: the step and the method in one program, for a pair whole)
=============  ==================================================================================
"""

from sswjax.graph.alignment import align_right
from sswjax.graph.match import (DEFAULT_CHUNK, SSWOutputs, aggregated_cost, carries_paths,
                                ssw_carried, ssw_cues, ssw_disparity, ssw_disparity_seeded,
                                ssw_outputs, ssw_outputs_seeded)
from sswjax.graph.scopes import Stage

__all__ = ["DEFAULT_CHUNK", "SSWOutputs", "Stage", "aggregated_cost", "align_right",
           "carries_paths", "ssw_carried", "ssw_cues", "ssw_disparity", "ssw_disparity_seeded",
           "ssw_outputs", "ssw_outputs_seeded"]
