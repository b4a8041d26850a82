"""Real data into the simlidar schema: KITTI front-view pulse crops and DVS barrel first spikes.

The converted datasets sit beside the generated ones (same directory layout, ``delays`` and
``labels`` in every split), so loading, ``verify`` and the benchmark take them as they are.
``docs/converters.md`` describes both converters.
"""

from simlidar.convert.dvs import convert_dvs_barrel
from simlidar.convert.kitti import convert_kitti

__all__ = ["convert_dvs_barrel", "convert_kitti"]
