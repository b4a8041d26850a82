"""The KITTI source in one place: the KITTI 3D object benchmark's files as simlidar both writes
them (a sweep's KITTI export, :mod:`simlidar.generator.exports`) and reads them (the KITTI
converter, :mod:`simlidar.convert.kitti_files`): a scan's point layout and a label line's
columns; and what the converted datasets declare (:data:`SOURCE`: version line, schema, card
lines, prose). The converter itself is :mod:`simlidar.convert.kitti`.

    velodyne/NNNNNN.bin  SCAN_COLUMNS a point, each a SCAN_DTYPE, no header (Velodyne frame)
    label_2/NNNNNN.txt   one object per line, the LABEL_COLUMNS (camera frame), space-separated
"""

import numpy as np

from simlidar.dataset.source import DELAYS_AND_LABELS, DELAYS_AND_LABELS_FIELDS, About, Source

SCAN_COLUMNS = ("x", "y", "z", "reflectance")  # metres; reflectance 0..1
SCAN_DTYPE = np.dtype("<f4")
LABEL_COLUMNS = tuple(
    "type truncated occluded alpha bbox_left bbox_top bbox_right bbox_bottom h w l x y z "
    "rotation_y".split()
)

ABOUT = About(
    name="KITTI front-view pulses (simlidar)",
    license="cc-by-nc-sa-3.0",
    license_url="https://creativecommons.org/licenses/by-nc-sa/3.0/",
    homepage="https://www.cvlibs.net/datasets/kitti/eval_object.php?obj_benchmark=3d",
    tags=("lidar", "spiking-neural-networks", "temporal-coding", "kitti", "velodyne-hdl-64e"),
    description=(
        "Real LiDAR temporal pulses: every labelled object of the KITTI 3D object benchmark "
        "(training split) as a fixed-size crop of the Velodyne HDL-64E scan projected into the "
        "expanded front view, each cell holding the round-trip delay of the nearest return, "
        "normalised to [0, 1] (1 = no return). Eight classes: Car, Van, Truck, Pedestrian, "
        "Person_sitting, Cyclist, Tram, Misc. Made as in Wang et al. (2020), in the schema of "
        "simlidar's synthetic Sim LiDAR datasets, so that the same networks run on both."
    ),
    delay_meaning=(
        "A value is the round-trip time of flight to the nearest Velodyne point in a front-view "
        "cell divided by the time of flight at 100 m (`tof_max_ns`): 0.1 means a return from "
        "10 m. 1.0 means no return: no point fell into the cell, or it was 100 m or farther. "
        "Row r is an elevation bin (highest first), column c an azimuth bin (left to right)."
    ),
    conversion=(
        "Each scan is projected into the expanded front view: x_front = floor(atan2(-y, x) * "
        "180 / (pi * res_h)), y_front = floor(-atan2(z, d) * 180 / (pi * res_v)), d = sqrt(x^2 "
        "+ y^2), in the Velodyne frame (x forward, y left, z up). A cell keeps its nearest point; "
        "its range r = sqrt(x^2 + y^2 + z^2) becomes the time of flight 2 r / c. Each labelled "
        "3D box is moved from camera to Velodyne coordinates (inverse of `R0_rect`, then of "
        "`Tr_velo_to_cam`), and the crop is centred on the cell of the box's centre; columns "
        "wrap around at 180 degrees. DontCare boxes are skipped. Frames, never objects, are "
        "split between train and test, by a seeded random choice."
    ),
    uses=(
        "Training and benchmarking classifiers of LiDAR temporal pulses, spiking networks with "
        "temporal coding in particular, on real scans, next to the synthetic Sim LiDAR data."
    ),
    out_of_scope=(
        "Not a detection benchmark: crops are centred on the ground-truth boxes. KITTI's "
        "license forbids commercial use; the derived data inherits it."
    ),
    source_citation="""@inproceedings{geiger2012kitti,
  title     = {Are we ready for Autonomous Driving? The KITTI Vision Benchmark Suite},
  author    = {Geiger, Andreas and Lenz, Philip and Urtasun, Raquel},
  booktitle = {Conference on Computer Vision and Pattern Recognition (CVPR)},
  year      = {2012}
}""",
)

SOURCE = Source(
    name="kitti",
    version="1.0.0",
    dates={"1.0.0": "2026-11-22"},
    notes={
        "1.0.0": (
            "First release: KITTI 3D object benchmark scans projected into the expanded "
            "front view, one fixed-size crop of normalised pulse delays per labelled object."
        )
    },
    schema={
        **DELAYS_AND_LABELS,
        "frame": ("int64", ("N",)),
        "crop_origin": ("int32", ("N", 2)),
        "box_corners_m": ("float32", ("N", 8, 3)),
        "box_points": ("int32", ("N",)),
        "truncated": ("float32", ("N",)),
        "occluded": ("uint8", ("N",)),
    },
    attrs=("classes", "input_sha256"),
    fields={  # one line per dataset; the full tables are in docs/converters.md
        **DELAYS_AND_LABELS_FIELDS,
        "frame": "KITTI frame number (the file name's digits)",
        "crop_origin": "front-view row y_front and column x_front of the crop's top-left cell",
        "box_corners_m": "the 3D box's 8 corners in the Velodyne frame, m",
        "box_points": "Velodyne points inside the 3D box",
        "truncated": "KITTI truncation, 0 (none) to 1",
        "occluded": "KITTI occlusion, 0 (visible) to 3 (unknown)",
    },
    call=("simlidar.convert", "convert_kitti", "ROOT"),  # the benchmark's training folder
    about=ABOUT,
)
