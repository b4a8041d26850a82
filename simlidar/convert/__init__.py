"""Real data into the simlidar schema: KITTI front-view pulse crops and DVS barrel first spikes.

The converted datasets sit beside the generated ones (same directory layout, ``delays`` and
``labels`` in every split), so loading, ``verify`` and the benchmark take them as they are.
``docs/converters.md`` describes both converters. The converters load on first use, so that
their options (:mod:`simlidar.convert.config`) import without them.
"""

__all__ = ["convert_dvs_barrel", "convert_kitti"]


def __getattr__(name: str):
    if name == "convert_kitti":
        from simlidar.convert.kitti import convert_kitti

        return convert_kitti
    if name == "convert_dvs_barrel":
        from simlidar.convert.dvs import convert_dvs_barrel

        return convert_dvs_barrel
    raise AttributeError(f"module 'simlidar.convert' has no attribute {name!r}")
