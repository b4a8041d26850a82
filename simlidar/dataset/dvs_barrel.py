"""The DVS barrel source in one place: what the datasets converted from the event-camera
recordings of Orchard et al. (2015) declare (:data:`SOURCE`: version line, schema, card lines,
prose) and the classes they name. The converter itself is :mod:`simlidar.convert.dvs`."""

from simlidar.dataset.source import DELAYS_AND_LABELS, DELAYS_AND_LABELS_FIELDS, About, Source

CLASSES = tuple("0123456789ABCDEFGHIJKLMNOPQRSTUVWXYZ")  # the 36 characters, ASCII order

ABOUT = About(
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

SOURCE = Source(
    name="dvs-barrel",
    version="1.0.0",
    dates={"1.0.0": "2026-11-22"},
    notes={
        "1.0.0": (
            "First release: DVS barrel recordings as 32 x 32 first-spike times, with the raw "
            "events alongside."
        )
    },
    schema={
        **DELAYS_AND_LABELS,
        "recording": ("int64", ("N",)),
        "event_start": ("int64", ("N",)),
        "event_count": ("int64", ("N",)),
        "event_x": ("uint8", ("E",)),
        "event_y": ("uint8", ("E",)),
        "event_p": ("int8", ("E",)),
        "event_t_us": ("int64", ("E",)),
    },
    attrs=("classes", "input_sha256"),
    fields={  # one line per dataset; the full tables are in docs/converters.md
        **DELAYS_AND_LABELS_FIELDS,
        "recording": "index of the recording in the ROI struct array (0-based)",
        "event_start": "row of the sample's first event in the event_* datasets",
        "event_count": "number of events of the sample",
        "event_x": "event x address, 0-based (column)",
        "event_y": "event y address, 0-based (row)",
        "event_p": "event polarity as recorded",
        "event_t_us": "event timestamp as recorded, microseconds",
    },
    call=("simlidar.convert", "convert_dvs_barrel", "FILE.mat"),
    about=ABOUT,
)
