"""What a converted dataset says about itself: the constants its card and Croissant metadata are
made of, one :class:`About` per source (the generator's are in :mod:`simlidar.generator.about`)."""

from dataclasses import dataclass


@dataclass(frozen=True)
class About:
    name: str  # the dataset's pretty name
    license: str  # Hugging Face license id of the source data
    license_url: str
    homepage: str  # where the source data is published
    tags: tuple[str, ...]
    description: str
    delay_meaning: str  # what one value of `delays` means
    conversion: str  # how the source became delays (the card's "Conversion" section)
    uses: str
    out_of_scope: str
    source_citation: str  # BibTeX of the source data


KITTI = About(
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

DVS_BARREL = About(
    name="DVS barrel first spikes (simlidar)",
    license="unknown",
    license_url="https://doi.org/10.1109/TPAMI.2015.2392947",
    homepage="https://doi.org/10.1109/TPAMI.2015.2392947",
    tags=("dvs", "event-camera", "spiking-neural-networks", "temporal-coding", "neuromorphic"),
    description=(
        "Event-camera recordings of 36 characters (0-9, A-Z) on a rotating barrel (Orchard et "
        "al. 2015), each recording cropped to 32 x 32 pixels and turned into the time of the "
        "first spike of every pixel, normalised to [0, 1] (1 = no spike); the raw events are "
        "kept alongside for other encodings. In the schema of simlidar's Sim LiDAR datasets, as "
        "used by Wang et al. (2020)."
    ),
    delay_meaning=(
        "A value is the time from a recording's first event to the first event of a pixel, "
        "either polarity, divided by the time window `time_window_us`. 1.0 means no spike in "
        "the window. Row r is the pixel's y address, column c its x address (0-based)."
    ),
    conversion=(
        "Every entry of the struct array `ROI` is one recording (one sample): its x and y "
        "addresses, polarities and timestamps (microseconds) are read, the addresses made "
        "0-based, and each pixel's first timestamp, less the recording's first, divided by the "
        "window. Recordings, never events, are split between train and test, per class, by a "
        "seeded random choice."
    ),
    uses="Training and benchmarking spiking networks with time-to-first-spike coding on real "
    "event-camera data.",
    out_of_scope="A tiny data set (a few recordings per class): accuracy on it says little "
    "about event-camera recognition in general.",
    source_citation="""@article{orchard2015hfirst,
  title   = {{HFirst}: A Temporal Approach to Object Recognition},
  author  = {Orchard, Garrick and Meyer, Cedric and Etienne-Cummings, Ralph and Posch,
             Christoph and Thakor, Nitish and Benosman, Ryad},
  journal = {IEEE Transactions on Pattern Analysis and Machine Intelligence},
  volume  = {37},
  number  = {10},
  pages   = {2028--2040},
  year    = {2015}
}""",
)

ABOUT = {"kitti": KITTI, "dvs-barrel": DVS_BARREL}
