"""The KITTI 3D object benchmark's files as simlidar both writes them (a sweep's KITTI export,
:mod:`simlidar.generator.exports`) and reads them (the KITTI converter,
:mod:`simlidar.convert.kitti_files`): a scan's point layout and a label line's columns.

    velodyne/NNNNNN.bin  SCAN_COLUMNS a point, each a SCAN_DTYPE, no header (Velodyne frame)
    label_2/NNNNNN.txt   one object per line, the LABEL_COLUMNS (camera frame), space-separated
"""

import numpy as np

SCAN_COLUMNS = ("x", "y", "z", "reflectance")  # metres; reflectance 0..1
SCAN_DTYPE = np.dtype("<f4")
LABEL_COLUMNS = tuple(
    "type truncated occluded alpha bbox_left bbox_top bbox_right bbox_bottom h w l x y z "
    "rotation_y".split()
)
