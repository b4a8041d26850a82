"""Triangles into an embreex scene without embreex's element-by-element copy.

``embreex.mesh_construction.TriangleMesh`` copies every vertex coordinate into Embree's buffer
through a Python-level index: about 0.6 us a triangle, once the largest single cost of
generation (docs/performance.md). Embree's C API can instead read a numpy array in place
(``rtcSetSharedGeometryBuffer``). :func:`attach_triangles` calls that API through ctypes, on
the Embree library embreex itself loaded, and attaches the geometry to an embreex
``EmbreeScene``. Everything else stays embreex's: the scene, the BVH build at the first ``run``
(where Embree reads the arrays) and the ray queries (one ``rtcIntersect1`` per ray), so the hits
are those of ``TriangleMesh``: same float32 vertices, same scene, same kernel.

The library is embreex's own: its symbols are looked up through the handle of embreex's
``rtcore_scene`` extension module, which resolves them in the libraries that module loaded.
The scene handle is a C field of embreex's ``EmbreeScene`` (declared in embreex's
``rtcore_scene.pxd``: ``scene_i``, ``is_committed``, ``device``), not a Python attribute, so it
is read from the object's memory. The layout is checked once per process without following any
pointer: the object size, the ``device`` field holding the very device object passed in, and
the public ``is_committed`` field moving when Python sets it. Embree must report major version
4. Where any of this fails, or raises, :func:`attach_triangles` uses ``TriangleMesh``: slower,
same hits. It then says so once per process (a warning naming the cause), and
:func:`ray_casting` (``simlidar --version``) tells which path this machine takes.
"""

import ctypes
import warnings
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


@cache
def device():
    """The embreex device every scene of this process is made on."""
    import embreex.rtcore as rtc

    return rtc.EmbreeDevice()


def new_scene():
    """An empty embreex ``EmbreeScene`` on :func:`device`."""
    import embreex.rtcore_scene as rtcs

    return rtcs.EmbreeScene(device())


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
def _probe():
    """(ctypes handle on embreex's Embree, the EmbreeScene class checked), or (None, why not)."""
    try:
        return _open()
    except Exception as exc:  # an embreex or Embree unlike the one this module knows: fall back
        return None, f"probing embreex raised {type(exc).__name__}: {exc}"


def _embree():
    """(ctypes handle on embreex's Embree, the EmbreeScene class checked), or None."""
    return _probe()[0]


def _open():
    import embreex.rtcore_scene as rtcs

    if not _layout_ok(rtcs.EmbreeScene, device()):
        return None, "embreex's EmbreeScene has a C layout this module does not know"
    lib = ctypes.CDLL(rtcs.__file__)  # embreex's module: its symbols are embreex's Embree
    p, size, enum = ctypes.c_void_p, ctypes.c_size_t, ctypes.c_int
    for name, restype, argtypes in [
        ("rtcNewDevice", p, [ctypes.c_char_p]),
        ("rtcGetSceneDevice", p, [p]),
        ("rtcReleaseDevice", None, [p]),
        ("rtcGetDeviceProperty", ctypes.c_ssize_t, [p, enum]),
        ("rtcGetDeviceError", ctypes.c_int, [p]),
        ("rtcNewGeometry", p, [p, enum]),
        ("rtcSetSharedGeometryBuffer", None, [p, enum, ctypes.c_uint, enum, p, size, size, size]),
        ("rtcCommitGeometry", None, [p]),
        ("rtcAttachGeometry", ctypes.c_uint, [p, p]),
        ("rtcReleaseGeometry", None, [p]),
    ]:
        fn = getattr(lib, name)
        fn.restype, fn.argtypes = restype, argtypes
    handle = lib.rtcNewDevice(None)
    if not handle:
        return None, "Embree could not make a device"
    try:
        major = lib.rtcGetDeviceProperty(handle, _PROPERTY_VERSION_MAJOR)
    finally:
        lib.rtcReleaseDevice(handle)
    if major != 4:
        return None, f"embreex's Embree is version {major}; expected 4"
    return (lib, rtcs.EmbreeScene), ""


def shared_buffers() -> bool:
    """Whether :func:`attach_triangles` shares numpy buffers with Embree on this machine."""
    return _embree() is not None


def ray_casting() -> str:
    """Which path ray casting takes on this machine, in a few words (``simlidar --version``)."""
    if shared_buffers():
        return "Embree 4, triangles shared with numpy (simlidar.sensor.embree)"
    why = _probe()[1] or "shared buffers unavailable"
    return f"embreex's TriangleMesh, a copy a triangle: slower, the same hits ({why})"


@cache
def _say_fallback() -> None:
    """The fallback's one warning in this process."""
    warnings.warn(f"ray casting through {ray_casting()}", stacklevel=2)


def attach_triangles(embree_scene, triangles: np.ndarray, shared: bool = True):
    """Add a triangle mesh to an embreex ``EmbreeScene`` that has not run yet.

    triangles : (T, 3, 3) float, rounded to float32 as Embree stores them
    shared : use the shared buffers where available (off only to compare with ``TriangleMesh``)
    returns : what must stay alive until the scene has run (Embree reads the arrays when it
        builds the BVH, at the first ``run``)
    """
    # float64 on purpose: embreex converts element by element, faster from float64, and rounds
    # to float32 exactly as astype does
    triangles = np.asarray(triangles, np.float64)
    opened = _embree() if shared else None
    if opened is None:
        import embreex.mesh_construction as mc

        if shared:
            _say_fallback()

        return mc.TriangleMesh(embree_scene, triangles)
    n = len(triangles)
    # 16-byte rows, as TriangleMesh lays them out: Embree reads a vertex with one 16-byte load
    vertices = np.zeros((3 * n, 4), np.float32)
    vertices[:, :3] = triangles.reshape(-1, 3)
    return attach_vertices(embree_scene, vertices)


def attach_vertices(embree_scene, vertices: np.ndarray):
    """Add a triangle mesh, already in Embree's layout, to an embreex ``EmbreeScene`` that has
    not run yet, in place (the shared buffers: :func:`shared_buffers` must be true).

    vertices : (3 T, 4) float32, C-contiguous: triangle k's corners are rows 3k, 3k + 1 and
        3k + 2, one 16-byte row a vertex (the fourth column unused), as :func:`attach_triangles`
        and :func:`simlidar.sensor.cast_kernels.pack_vertices` lay them out
    returns : what must stay alive until the scene has run (the vertices and their indices)
    """
    opened = _embree()
    if opened is None:
        raise RuntimeError(f"shared buffers are unavailable: {_probe()[1]}")
    lib, scene_type = opened
    if not isinstance(embree_scene, scene_type):
        raise TypeError(f"expected an embreex EmbreeScene, got {type(embree_scene).__name__}")
    if vertices.dtype != np.float32 or vertices.ndim != 2 or vertices.shape[1] != 4:
        got = f"{vertices.dtype} {vertices.shape}"
        raise ValueError(f"expected (3 T, 4) float32 vertices, got {got}")
    if len(vertices) % 3 or not vertices.flags.c_contiguous:
        raise ValueError(f"expected C-contiguous vertices, 3 a triangle, got {len(vertices)} rows")
    n = len(vertices) // 3
    indices = np.arange(3 * n, dtype=np.uint32).reshape(n, 3)
    scene = _word(embree_scene, _SCENE_AT)
    handle = lib.rtcGetSceneDevice(scene)
    lib.rtcGetDeviceError(handle)  # clear an earlier, unrelated error of this thread
    try:
        geometry = lib.rtcNewGeometry(handle, _GEOMETRY_TRIANGLE)
        lib.rtcSetSharedGeometryBuffer(
            geometry, _BUFFER_VERTEX, 0, _FORMAT_FLOAT3, vertices.ctypes.data, 0, 16, 3 * n
        )
        lib.rtcSetSharedGeometryBuffer(
            geometry, _BUFFER_INDEX, 0, _FORMAT_UINT3, indices.ctypes.data, 0, 12, n
        )
        lib.rtcCommitGeometry(geometry)
        lib.rtcAttachGeometry(scene, geometry)
        lib.rtcReleaseGeometry(geometry)
        error = lib.rtcGetDeviceError(handle)
    finally:
        lib.rtcReleaseDevice(handle)
    if error:
        raise RuntimeError(f"Embree error {error} while attaching {n} triangles")
    return vertices, indices
