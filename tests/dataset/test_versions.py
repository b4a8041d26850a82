"""The release notes a dataset's card lists (simlidar/dataset/version.py: notes_until): its own
version's and the earlier ones, never fewer than a card listed before the rule (up to 4.1.0),
so that a new release changes no card written before it."""

from simlidar.dataset.version import RELEASE_NOTES, SOURCES, notes_until


def test_a_card_lists_its_notes_up_to_its_own_version_and_never_fewer_than_before():
    versions = list(RELEASE_NOTES)
    assert versions[:5] == ["1.0.0", "2.0.0", "3.0.0", "4.0.0", "4.1.0"]
    for old in ("1.0.0", "2.0.0", "3.0.0", "4.0.0", "4.1.0"):  # what they listed until 4.1.0
        assert list(notes_until(RELEASE_NOTES, old)) == versions[:5]
    assert list(notes_until(RELEASE_NOTES, "4.2.0")) == versions[:6]
    assert notes_until(RELEASE_NOTES, "not a version") == RELEASE_NOTES
    # a later release is not listed by the card of an earlier dataset
    later = RELEASE_NOTES | {"9.0.0": "a later release"}
    assert "9.0.0" not in notes_until(later, "4.2.0")
    # the converters' lines: all of theirs
    for _, _, notes in SOURCES.values():
        assert notes_until(notes, "1.0.0").keys() >= {"1.0.0"}
