"""Triangles into an embreex scene without embreex's element-by-element copy.

``embreex.mesh_construction.TriangleMesh`` copies every vertex coordinate into Embree's buffer
through a Python-level index: about 0.7 us a triangle, the largest single cost of generation
(docs/performance.md). Embree's C API can instead use a numpy array in place
(``rtcSetSharedGeometryBuffer``). :func:`attach_triangles` calls that API through ctypes, on the
Embree library embreex itself loaded, and attaches the geometry to an embreex ``EmbreeScene``.
Everything else stays embreex's: the scene, the BVH build at the first ``run`` and the ray
queries (one ``rtcIntersect1`` per ray), so the hits are those of ``TriangleMesh``: same float32
vertices, same scene, same kernel.

The scene handle is a C field of embreex's ``EmbreeScene`` (declared in embreex's
``rtcore_scene.pxd``: ``scene_i``, ``is_committed``, ``device``), not a Python attribute, so it
is read from the object's memory. The layout is checked once per process before any pointer is
used: the object size, the ``device`` field holding the very device object passed in, and the
public ``is_committed`` field moving when Python sets it; then Embree itself must report the
same device for two scenes and version 4. The library is found in ``/proc/self/maps`` (the file
embreex loaded, Linux). Where any of this fails, :func:`attach_triangles` uses ``TriangleMesh``:
slower, same hits.
"""

import ctypes
from functools import cache

import numpy as np

_GEOMETRY_TRIANGLE = 0  # RTC_GEOMETRY_TYPE_TRIANGLE
_BUFFER_INDEX, _BUFFER_VERTEX = 0, 1  # RTC_BUFFER_TYPE_*
_FORMAT_UINT3, _FORMAT_FLOAT3 = 0x5003, 0x9003  # RTC_FORMAT_*
_PROPERTY_VERSION_MAJOR = 1  # RTC_DEVICE_PROPERTY_VERSION_MAJOR
_PTR = ctypes.sizeof(ctypes.c_void_p)
# EmbreeScene's C struct: PyObject header (2 words), scene_i, is_committed (int, padded to a
# word), device (a PyObject pointer)
_SCENE_AT, _COMMITTED_AT, _DEVICE_AT, _SCENE_SIZE = 2 * _PTR, 3 * _PTR, 4 * _PTR, 5 * _PTR


def _loaded_library() -> str | None:
    """Path of the Embree 4 library mapped into this process (embreex's), or None."""
    import embreex.rtcore  # noqa: F401  (loads the library)

    try:
        with open("/proc/self/maps") as maps:
            paths = {line.split(maxsplit=5)[-1].strip() for line in maps if "libembree4" in line}
    except OSError:
        return None
    return paths.pop() if len(paths) == 1 else None


def _word(obj, at: int) -> int:
    return ctypes.c_void_p.from_address(id(obj) + at).value or 0


def _layout_ok(scene_type, device) -> bool:
    """Whether EmbreeScene objects have the C layout this module reads."""
    if scene_type.__basicsize__ != _SCENE_SIZE:
        return False
    probe = scene_type(device)
    if _word(probe, _DEVICE_AT) != id(device):
        return False
    committed = ctypes.c_int.from_address(id(probe) + _COMMITTED_AT)
    for value in (0x5A5A5A5, 0):
        probe.is_committed = value
        if committed.value != value:
            return False
    return _word(probe, _SCENE_AT) != 0


@cache
def _embree():
    """The ctypes handle on embreex's Embree library, or None where the shared path is off."""
    import embreex.rtcore as rtc
    import embreex.rtcore_scene as rtcs

    path = _loaded_library()
    device = rtc.EmbreeDevice()
    if path is None or not _layout_ok(rtcs.EmbreeScene, device):
        return None
    lib = ctypes.CDLL(path)
    p, size = ctypes.c_void_p, ctypes.c_size_t
    for name, restype, argtypes in [
        ("rtcGetSceneDevice", p, [p]),
        ("rtcReleaseDevice", None, [p]),
        ("rtcGetDeviceProperty", ctypes.c_ssize_t, [p, ctypes.c_int]),
        ("rtcGetDeviceError", ctypes.c_int, [p]),
        ("rtcNewGeometry", p, [p, ctypes.c_int]),
        (
            "rtcSetSharedGeometryBuffer",
            None,
            [p, ctypes.c_int, ctypes.c_uint, ctypes.c_int, p, size, size, size],
        ),  # fmt: skip
        ("rtcCommitGeometry", None, [p]),
        ("rtcAttachGeometry", ctypes.c_uint, [p, p]),
        ("rtcReleaseGeometry", None, [p]),
    ]:
        fn = getattr(lib, name)
        fn.restype, fn.argtypes = restype, argtypes
    devices = []
    for scene in (rtcs.EmbreeScene(device), rtcs.EmbreeScene(device)):
        handle = lib.rtcGetSceneDevice(_word(scene, _SCENE_AT))
        devices.append(handle)
        if handle:
            lib.rtcReleaseDevice(handle)
    if not devices[0] or devices[0] != devices[1]:
        return None
    if lib.rtcGetDeviceProperty(devices[0], _PROPERTY_VERSION_MAJOR) != 4:
        return None
    return lib


def shared_buffers() -> bool:
    """Whether :func:`attach_triangles` shares numpy buffers with Embree on this machine."""
    return _embree() is not None


def attach_triangles(embree_scene, triangles: np.ndarray, shared: bool = True):
    """Add a triangle mesh to an embreex ``EmbreeScene`` that has not run yet.

    triangles : (T, 3, 3) float, rounded to float32 as Embree stores them
    shared : use the shared buffers where available (off only to compare with ``TriangleMesh``)
    returns : what must stay alive until the scene is released (Embree reads these arrays)
    """
    lib = _embree() if shared else None
    if lib is None:
        import embreex.mesh_construction as mc

        # float64 on purpose: embreex converts element by element, faster from float64, and
        # rounds to float32 exactly as astype would
        return mc.TriangleMesh(embree_scene, np.asarray(triangles, np.float64))
    n = len(triangles)
    # 16-byte rows, as TriangleMesh lays them out: Embree reads a vertex with one 16-byte load
    vertices = np.zeros((3 * n, 4), np.float32)
    vertices[:, :3] = triangles.reshape(-1, 3)
    indices = np.arange(3 * n, dtype=np.uint32).reshape(n, 3)
    scene = _word(embree_scene, _SCENE_AT)
    device = lib.rtcGetSceneDevice(scene)
    try:
        geometry = lib.rtcNewGeometry(device, _GEOMETRY_TRIANGLE)
        lib.rtcSetSharedGeometryBuffer(geometry, _BUFFER_VERTEX, 0, _FORMAT_FLOAT3,
                                       vertices.ctypes.data, 0, 16, 3 * n)  # fmt: skip
        lib.rtcSetSharedGeometryBuffer(geometry, _BUFFER_INDEX, 0, _FORMAT_UINT3,
                                       indices.ctypes.data, 0, 12, n)  # fmt: skip
        lib.rtcCommitGeometry(geometry)
        lib.rtcAttachGeometry(scene, geometry)
        lib.rtcReleaseGeometry(geometry)
        error = lib.rtcGetDeviceError(device)
    finally:
        lib.rtcReleaseDevice(device)
    if error:
        raise RuntimeError(f"Embree error {error} while attaching {n} triangles")
    return vertices, indices
