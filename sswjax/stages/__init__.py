"""The algorithm's stages, one module per stage, each a family of pure functions on arrays.

Data flows through them in this order (``sswjax.pipeline`` composes them into one jitted graph):

===============  =================================================================================
``color``        colour conversions: sRGB to CIELAB (for SLIC), BT.601 luma
``preprocess``   pre-processing of the images the cost sees (local contrast normalisation)
``cost``         matching cost: TAD, Sobel gradient, census; the cost slices (Eq. 1-5)
``segments``     SLIC superpixels and segment means (Eq. 6)
``filters``      side-window box and median filters, sorting-network medians
``aggregation``  segment-side-window aggregation (Eq. 7)
``baselines``    the baseline aggregators (box, BF, GF, iGF, MF)
``sgm``          semi-global optimisation of the aggregated volume (Hirschmuller 2008)
``selection``    winner-takes-all, the running fold of both views, sub-pixel, soft-argmin (Eq. 8)
``refinement``   left-right check and filling (Eq. 9)
``fill``         guided weighted-median fill of the rejected pixels (Eq. 9, weighted)
``confidence``   confidence measures and validity bits from the fold's cues and the refinement
``planes``       robust plane per superpixel, filling the pixels it supports
``pyramid``      halving and doubling of images and volumes (half-resolution SGM)
===============  =================================================================================
"""
