def test_every_converted_source_declares_each_dataset_its_release_and_its_prose():
    """A converted source is one module (simlidar.dataset.kitti, .dvs_barrel): its schema starts
    with the delays and labels every reader loads, each of its datasets has the line its card
    and Croissant give, its current version has release notes and a date, and its About has
    every text a card prints."""
    from simlidar.dataset.schema import CONVERTED_SCHEMAS, SOURCE_ATTRS
    from simlidar.dataset.version import CONVERTED, SOURCES

    assert set(CONVERTED) == {"kitti", "dvs-barrel", "simlidar-stream"}
    for name, source in CONVERTED.items():
        assert list(source.schema)[:2] == ["delays", "labels"]
        assert set(source.fields) == set(source.schema), name
        assert source.version in source.notes and source.version in source.dates
        assert all(getattr(source.about, f) for f in source.about.__dataclass_fields__), name
        assert SOURCES[name] == (source.version, source.dates, source.notes)
        assert CONVERTED_SCHEMAS[name] is source.schema and SOURCE_ATTRS[name] == source.attrs
