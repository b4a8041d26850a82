"""What a source of converted real data declares about its datasets, in one object: its version
line and release notes, its splits' datasets and attributes, the line each dataset gets in its
card, the call that makes it again, and its prose (:class:`About`).

Each converter's is one module of the dataset stage, beside the readers that check it
(:mod:`simlidar.dataset.kitti`, :mod:`simlidar.dataset.dvs_barrel`); its builder is
``simlidar/convert/<source>.py``. :data:`simlidar.dataset.version.CONVERTED` lists them.
"""

from dataclasses import dataclass, field


@dataclass(frozen=True)
class About:
    """What a converted dataset says about itself: the text its card and Croissant are made of."""

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


@dataclass(frozen=True)
class Source:
    """One source of converted datasets, by the name its splits' ``source`` attribute holds.

    name : the ``source`` attribute of its splits (``kitti``)
    version : the version its converter writes now (MAJOR.MINOR.PATCH)
    dates : version -> release date (croissant.json's datePublished)
    notes : version -> release notes (the card's "Versions")
    schema : dataset -> (dtype, shape), a shape's letters being N samples, E events, H rows,
        W columns
    attrs : the attributes a split always carries besides ``REQUIRED_ATTRS`` (its card reads
        them)
    fields : dataset -> one line on what it holds (the card's table and Croissant's fields)
    call : the library function that makes it (its module, its name) and its first argument
        before the output folder (None: none), the card's "Regenerate"
    about : its prose, licence and citation
    receiver_schema, receiver_fields : the datasets a split holds besides ``schema`` where it
        has a ``receiver`` attribute (a stream through a receiver), and their lines (with
        lines that replace ``fields``' there)
    receiver_about : its prose there (None: ``about``'s)
    """

    name: str
    version: str
    dates: dict[str, str]
    notes: dict[str, str]
    schema: dict[str, tuple[str, tuple]]
    attrs: tuple[str, ...]
    fields: dict[str, str]
    call: tuple[str, str, str | None]
    about: About
    receiver_schema: dict[str, tuple[str, tuple]] = field(default_factory=dict)
    receiver_fields: dict[str, str] = field(default_factory=dict)
    receiver_about: About | None = None

    def schema_of(self, receiver: bool) -> dict[str, tuple[str, tuple]]:
        """The datasets a split holds: ``schema``, and with a receiver ``receiver_schema``."""
        return self.schema | (self.receiver_schema if receiver else {})

    def fields_of(self, receiver: bool) -> dict[str, str]:
        """Their card lines, as :meth:`schema_of`."""
        return self.fields | (self.receiver_fields if receiver else {})

    def about_of(self, receiver: bool) -> About:
        """Its prose, as :meth:`schema_of`."""
        return self.receiver_about if receiver and self.receiver_about else self.about


# the two datasets every converted split holds, and their card lines
DELAYS_AND_LABELS = {
    "delays": ("float32", ("N", "H", "W")),
    "labels": ("int64", ("N",)),
}
DELAYS_AND_LABELS_FIELDS = {
    "delays": "normalised delays (1.0 = nothing in the window): the network input",
    "labels": "class index",
}
