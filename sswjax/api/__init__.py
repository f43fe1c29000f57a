"""The NumPy front door: user arrays in, NumPy maps out.

============  ===================================================================================
``images``    checks and conversion of the user's images
``ranges``    disparity ranges that start anywhere (negative too), by a shift of the right image
``match``     ``match`` and ``match_with_confidence``
``warmup``    ``warm_up``: compile ahead of time for the shapes to come
``batch``     batches of equal-size pairs, and pairs of many sizes, over all devices
``geometry``  depth maps and point clouds from a disparity map and a calibration
============  ===================================================================================
"""
