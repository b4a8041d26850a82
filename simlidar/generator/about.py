"""What a published Sim LiDAR dataset says about itself: the constants its card is made of.

The card (``README.md``) and ``croissant.json`` are generated from these and from the split
files' own attributes; nothing in them is typed twice.
"""

import re

NAME = "Sim LiDAR (simlidar)"
HOMEPAGE = "https://pypi.org/project/simlidar/"
LICENSE = "cc-by-4.0"  # Hugging Face license id of the generated data
LICENSE_URL = "https://creativecommons.org/licenses/by/4.0/"
CREATOR = "simlidar developers"
TAGS = [
    "lidar",
    "spiking-neural-networks",
    "temporal-coding",
    "neuromorphic",
    "synthetic",
    "autonomous-driving",
    "velodyne-vlp-16",
]

DESCRIPTION = (
    "Synthetic LiDAR temporal pulses: each sample is a 16 x W array of the round-trip delays of "
    "the pulses a simulated Velodyne VLP-16 fires into a procedurally built road scene, "
    "normalised to [0, 1] (1 = no return), with uniform noise. The classes are road layouts "
    "(tunnel, open road, lower bridge, upper bridge, two side walls, one side wall, street "
    "lamps on both sides, on one side) crossed with objects in the lane ahead (none, car, "
    "pedestrian, truck). An open, reproducible rebuild of the Sim LiDAR dataset of Wang et al. "
    "(2020), made for spiking networks with time-to-first-spike coding and for conventional "
    "baselines."
)

MOTIVATION = (
    "Wang et al. (2020) showed that a spiking network can classify raw LiDAR temporal pulses, "
    "and decide before all pulses have arrived, but their Sim LiDAR generator was never "
    "published. This dataset rebuilds it from a documented sensor model and declarative scene "
    "recipes, so that their results can be checked and extended, and so that spiking and "
    "conventional networks can be compared on identical, versioned data."
)

DELAY_MEANING = (
    "A value is the round-trip time of flight of one laser pulse divided by the time of flight "
    "at the sensor's maximum range: 0.1 means an echo from 10 m when the maximum range is "
    "100 m. 1.0 means that no echo arrived within the listening window (nothing hit, or out of "
    "range). Row r is one laser (highest elevation first), column c one azimuth bin (left to "
    "right)."
)

PREPROCESSING = (
    "None beyond the simulation: ranges are quantised to the sensor's 2 mm resolution, "
    "converted to times of flight and normalised. `delays` adds uniform noise U(0, a) to every "
    "pulse and clips at 1.0; `clean_delays` holds the same pulses without noise (after the "
    "optional delay shift). A sample whose object (or the layout's defining surface) is hit by "
    "too few pulses is drawn again, so every label is visible to the sensor."
)

USES = (
    "Training and benchmarking classifiers of LiDAR temporal pulses, in particular spiking "
    "networks with temporal coding (early decisions, spikes consumed, energy per decision) "
    "against CNN / VGG / ResNet baselines; studying robustness to timing noise; teaching."
)

OUT_OF_SCOPE = (
    "The scenes are simple geometric models: the data says nothing about real sensor artefacts "
    "(reflectivity, multipath, rain, beam divergence), and accuracy on it does not transfer to "
    "road safety. Do not use it to certify or validate perception for real vehicles."
)

DISTRIBUTION = (
    "A dataset directory holds `train.h5`, `test.h5` (HDF5), this card, `croissant.json` "
    "(Croissant 1.0 metadata), `preview.png` and `SHA256SUMS`. `simlidar pack` makes a "
    "`.tar.gz` with its `.sha256` for any web host, Zenodo or the Hugging Face Hub; `simlidar "
    "fetch URL` downloads, checks and verifies one. The data is released under CC BY 4.0."
)

MAINTENANCE = (
    "Versioned as MAJOR.MINOR.PATCH with the TensorFlow Datasets meaning (PATCH: same records; "
    "MINOR: fields added; MAJOR: records change). Every dataset can be regenerated bit for bit "
    "from the command below and the matching simlidar release; `simlidar verify` checks a copy."
)

CITATION = """@article{wang2020temporal,
  title   = {Temporal Pulses Driven Spiking Neural Network for Fast Object Recognition in
             Autonomous Driving},
  author  = {Wang, Wei and Zhou, Shibo and Li, Jingxi and Li, Xiaohua and Yuan, Junsong and
             Jin, Zhanpeng},
  journal = {arXiv preprint arXiv:2001.09220},
  year    = {2020}
}"""


def description(sensor) -> str:
    """:data:`DESCRIPTION` for a dataset of ``sensor`` (a :class:`~simlidar.sensor.Sensor`)."""
    return DESCRIPTION.replace("16 x W", f"{sensor.beams} x W").replace(
        "Velodyne VLP-16", sensor.model
    )


def tags(sensor) -> list[str]:
    """:data:`TAGS` for a dataset of ``sensor``: the sensor's tag names its model."""
    slug = re.sub(r"[^a-z0-9]+", "-", sensor.model.lower()).strip("-")
    return [slug if t == "velodyne-vlp-16" else t for t in TAGS]
