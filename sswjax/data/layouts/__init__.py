"""Stereo benchmark layouts: MiddEval3, KITTI 2012/2015, Middlebury 2001-2006 and ETH3D two-view.

Every layout is one :class:`Layout` object in :data:`LAYOUTS` and loads into the same
:class:`StereoScene` (array conventions in :mod:`sswjax.data.layouts.base`).

==============  ================================================================================
``base``        :class:`StereoScene`, the :class:`Layout` base class, the disparity-count rule
                (:func:`ndisp_from_ground_truth`) and the checks the layouts share
``middeval3``   MiddEval3 scene folders (``calib.txt``); :func:`find_data_root`
``kitti``       KITTI 2012 / 2015: one folder per view
``middlebury``  Middlebury 2001, 2003, 2005, 2006: one folder per scene, scaled integer GT
``eth3d``       ETH3D two-view: image folders beside ground-truth folders
``registry``    :data:`LAYOUTS`, :func:`detect_layout`, :func:`load_scenes`,
                :func:`load_scenes_checked`
==============  ================================================================================
"""

from sswjax.data.layouts.base import Layout, StereoScene, ndisp_from_ground_truth
from sswjax.data.layouts.middeval3 import find_data_root
from sswjax.data.layouts.registry import LAYOUTS, detect_layout, load_scenes, load_scenes_checked

__all__ = [
    "LAYOUTS",
    "Layout",
    "StereoScene",
    "detect_layout",
    "find_data_root",
    "load_scenes",
    "load_scenes_checked",
    "ndisp_from_ground_truth",
]
