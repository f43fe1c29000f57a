"""The algorithm's stages, one module per stage, each a family of pure functions on arrays.

Data flows through them in this order (:mod:`sswjax.graph` composes them into one jitted graph;
the configuration of each is in :mod:`sswjax.config`; ``reference`` holds the tests' oracles):

================  ================================================================================
``color``         colour conversions: sRGB to CIELAB (for SLIC), BT.601 luma
``preprocess``    pre-processing of the images the cost sees (local contrast normalisation)
``cost``          matching cost: TAD, Sobel gradient, census; the cost slices (Eq. 1-5)
``segments``      SLIC superpixels and segment means (Eq. 6)
``filters``       side-window box filters (Yin et al. 2019)
``medians``       sorting-network medians: square, separable, side-window
``aggregation``   segment-side-window aggregation (Eq. 7)
``baselines``     the baseline aggregators box, BF and MF, and the box means they share
``guided``        the guided filter and its iterated form (GF, iGF)
``quantisation``  the cost stored in int16 / uint8 levels for the paths, and their sums read back
``sgm``           semi-global optimisation of the aggregated volume (Hirschmuller 2008)
``cross_scale``   semi-global paths at half resolution with the fine cost's detail
``bands``         per-pixel disparity bands around an estimate (tSGM, Rothermel et al. 2012)
``selection``     the running fold of both views' winners, sub-pixel, soft-argmin (Eq. 8)
``checks``        the left-right distance and the uniqueness test (Eq. 9)
``background``    the background fill of the rejected pixels, the row's farther side (Eq. 9)
``fill``          guided weighted-median and vote fills of the rejected pixels (Eq. 9, weighted)
``confidence``    confidence measures and validity bits from the fold's cues and the refinement
``planes``        robust plane per superpixel, filling the pixels it supports
``pyramid``       halving and doubling of images and volumes (half-resolution SGM)
``upsampling``    the coarse map doubled back, guided by the fine image (coarse-to-fine)
``refit``         the doubled map's sub-pixel fit again, on the fine level's cost
``smoothing``     the gated joint-bilateral mean of the finished map
``buffers``       values written once instead of recomputed by each reader (XLA fusion)
``loops``         a pass repeated as one loop of the graph instead of unrolled (compile time)
``reference``     direct whole-volume versions the tests check the live stages against
================  ================================================================================
"""
