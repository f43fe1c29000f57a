"""Infrastructure for data: reading and writing the files of stereo data sets.

==================  ============================================================================
``io``              images, PFM files, disparity PNGs for display
``scaled``          integer disparity images of ``disparity * scale`` (KITTI's 16-bit PNG)
``calibration``     Middlebury ``calib.txt``: its keys, the left camera
``ply``             point clouds as PLY files
``layouts``         the benchmark layouts (MiddEval3, KITTI, Middlebury, ETH3D): telling a
                    folder's layout and loading its scenes
``download``        fetching and unpacking MiddEval3 and ETH3D
==================  ============================================================================
"""
