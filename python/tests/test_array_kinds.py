"""Every kind of array NumPy can hand over gives every entry point the answers, bit for bit, of
the plain array of the same values (C-ordered, aligned, native byte order, as NumPy reads it):
misaligned (a deserialized Dask chunk), read-only, Fortran-ordered, reversed (negative
strides), strided, misaligned and strided at once, byte-swapped, either half of the rows of an
array twice as wide (`rays[:, :3]` and `rays[:, 3:]` of an (N, 6) array) and every third row
of a longer one (both of which the ray and inside queries read in place), rows that overlap or
repeat, Python lists, and empty.
Arrays that cannot be read are refused with a TypeError or ValueError naming the argument;
nothing raises a PanicException."""

from types import SimpleNamespace

import numpy as np
import pytest

import hbv
from conftest import icosphere, random_rays


# -- Array kinds: each returns an array (or list) holding the values of `a` --------------------

def _misaligned(a):
    """C-contiguous at an odd address (np.frombuffer with offset=1): not aligned."""
    a = np.ascontiguousarray(a)
    out = np.frombuffer(bytearray(a.nbytes + 1), a.dtype, count=a.size, offset=1)
    out = out.reshape(a.shape)
    out[...] = a
    return out


def _read_only(a):
    out = a.copy()
    out.flags.writeable = False
    return out


def _reversed(a):
    """Stored back to front on every axis, read through negative strides."""
    back = (slice(None, None, -1),) * a.ndim
    return a[back].copy()[back]


def _strided(a):
    """Every other element of an array twice the size on every axis."""
    every_other = (slice(None, None, 2),) * a.ndim
    big = np.zeros(tuple(2 * s for s in a.shape), a.dtype)
    big[every_other] = a
    return big[every_other]


def _packed_field(a):
    """A field of a packed record after one byte of padding: misaligned and strided."""
    record = np.dtype([("pad", "u1"), ("x", a.dtype, a.shape[1:])])
    rows = np.zeros(a.shape[0], record)
    rows["x"] = a
    return rows["x"]


def _row_half(second):
    """A 2-D array as the first or second half of each row of a C-ordered array twice as wide,
    as `rays[:, :3]` and `rays[:, 3:]` of an (N, 6) array of rays; other arrays C-ordered."""
    def make(a):
        if a.ndim != 2:
            return np.ascontiguousarray(a)
        columns = a.shape[1]
        wide = np.zeros((a.shape[0], 2 * columns), a.dtype)
        half = wide[:, columns:] if second else wide[:, :columns]
        half[...] = a
        return half
    return make


def _every_third_row(a):
    """A 2-D array as every third row of a C-ordered array three times as long (rows nine
    items apart, read in place); other arrays C-ordered."""
    if a.ndim != 2:
        return np.ascontiguousarray(a)
    big = np.zeros((3 * a.shape[0],) + a.shape[1:], a.dtype)
    big[::3] = a
    return big[::3]


def _byte_swapped(a):
    return a.astype(a.dtype.newbyteorder())


KINDS = {
    "c_order": np.ascontiguousarray,
    "misaligned": _misaligned,
    "read_only": _read_only,
    "fortran": np.asfortranarray,
    "reversed": _reversed,
    "strided": _strided,
    "packed_field": _packed_field,
    "byte_swapped": _byte_swapped,
    "first_half_of_rows": _row_half(second=False),
    "second_half_of_rows": _row_half(second=True),
    "every_third_row": _every_third_row,
    "misaligned_byte_swapped": lambda a: _misaligned(_byte_swapped(a)),
    "list": lambda a: a.tolist(),
}


def _plain(values):
    """What NumPy reads `values` as, C-ordered, aligned and in native byte order."""
    array = np.asarray(values)
    return array.astype(array.dtype.newbyteorder("="), order="C")


def _only_arrays(make):
    """`make` applied to arrays; numbers and None pass as they are."""
    return lambda a: make(a) if isinstance(a, np.ndarray) else a


# -- Inputs and structures ------------------------------------------------------------------

SPHERE_V, SPHERE_F = icosphere(2, radius=0.8)
SPHERE = hbv.Mesh(SPHERE_V, SPHERE_F)
BVH = hbv.BVH(SPHERE)
GRID = hbv.Grid(SPHERE)


def _shifted(x):
    m = np.eye(4)
    m[0, 3] = x
    return m


def _scene():
    scene = hbv.Scene()
    scene.add(SPHERE, mask=1)
    scene.add(BVH, _shifted(1.0), mask=2)
    return scene


SCENE = _scene()


def _inputs(rows, dtype=np.float64, seed=7, faces_dtype=np.int64):
    """Rays, bounds, masks, points, a mesh's arrays and an attribute: `rows` rays and points."""
    rng = np.random.default_rng(seed)
    o, d = random_rays(max(rows, 1), seed=seed)
    prim = rng.integers(-1, len(SPHERE_F), rows)
    return SimpleNamespace(
        o=o[:rows].astype(dtype),
        d=d[:rows].astype(dtype),
        tmin=rng.uniform(0.0, 0.1, rows).astype(dtype),
        tmax=rng.uniform(0.5, 4.0, rows).astype(dtype),
        mask=rng.integers(0, 4, rows).astype(np.uint32),
        points=rng.uniform(-1.5, 1.5, (rows, 3)).astype(dtype),
        vertices=SPHERE_V.astype(dtype),
        faces=SPHERE_F.astype(faces_dtype),
        transform=np.array([[0.0, -1.0, 0.0, 0.3], [1.0, 0.0, 0.0, 0.1],
                            [0.0, 0.0, 2.0, -0.2], [0.0, 0.0, 0.0, 1.0]]),
        attribute=rng.normal(size=(len(SPHERE_V), 2)).astype(dtype),
        prim=prim,
        u=rng.uniform(0, 0.5, rows).astype(dtype),
        v=rng.uniform(0, 0.5, rows).astype(dtype),
    )


def _rays(m, x):
    return (m(x.o), m(x.d)), {"tmin": m(x.tmin), "tmax": m(x.tmax)}


def _ray_query(structure, query):
    def run(m, x):
        args, bounds = _rays(m, x)
        return getattr(structure, query)(*args, **bounds)
    return run


def _scene_ray_query(query):
    def run(m, x):
        args, bounds = _rays(m, x)
        return getattr(SCENE, query)(*args, **bounds, mask=m(x.mask))
    return run


def _mesh(m, x):
    mesh = hbv.Mesh(m(x.vertices), m(x.faces))
    return mesh.vertices, mesh.faces


def _scene_add(m, x):
    scene = hbv.Scene()
    scene.add((m(x.vertices), m(x.faces)), m(x.transform), mask=3)
    args, bounds = _rays(m, x)
    return scene.intersect(*args, **bounds)


def _scene_set_transform(m, x):
    scene = _scene()
    scene.set_transform(1, m(x.transform))
    args, bounds = _rays(m, x)
    return scene.intersect(*args, **bounds, mask=m(x.mask))


ENTRY_POINTS = {
    "Mesh": _mesh,
    **{f"BVH.{q}": _ray_query(BVH, q) for q in ("intersect", "occluded", "intersect_all", "count")},
    **{f"Grid.{q}": _ray_query(GRID, q) for q in ("intersect", "occluded", "intersect_all", "count")},
    **{f"Scene.{q}": _scene_ray_query(q) for q in ("intersect", "occluded", "intersect_all", "count")},
    "BVH.contains": lambda m, x: BVH.contains(m(x.points)),
    "BVH.closest_point": lambda m, x: BVH.closest_point(m(x.points)),
    "BVH.signed_distance": lambda m, x: BVH.signed_distance(m(x.points)),
    "Grid.contains": lambda m, x: GRID.contains(m(x.points)),
    "Scene.contains": lambda m, x: SCENE.contains(m(x.points), mask=m(x.mask)),
    "Scene.closest_point": lambda m, x: SCENE.closest_point(m(x.points), mask=m(x.mask)),
    "Scene.add": _scene_add,
    "Scene.set_transform": _scene_set_transform,
    "interpolate": lambda m, x: hbv.interpolate(m(x.faces), m(x.attribute), m(x.prim), m(x.u), m(x.v)),
}


# -- Checks ---------------------------------------------------------------------------------

def _answer(entry, make, x):
    """The entry point's answer; a PanicException fails the test with its message."""
    try:
        return ENTRY_POINTS[entry](_only_arrays(make), x)
    except BaseException as e:  # a panic is a BaseException, not an Exception
        if type(e).__name__ == "PanicException":
            pytest.fail(f"{entry} panicked: {e}")
        raise


def _assert_same_bits(got, want, where):
    if isinstance(want, dict):
        assert got.keys() == want.keys(), where
        for k in want:
            _assert_same_bits(got[k], want[k], f"{where}[{k!r}]")
    elif isinstance(want, tuple):
        assert isinstance(got, tuple) and len(got) == len(want), where
        for k, (g, w) in enumerate(zip(got, want)):
            _assert_same_bits(g, w, f"{where}[{k}]")
    else:
        assert (got.dtype, got.shape) == (want.dtype, want.shape), where
        assert np.ascontiguousarray(got).tobytes() == np.ascontiguousarray(want).tobytes(), where


def _check_same_as_plain(entry, make, x):
    """The answer on `make`'s arrays equals, bit for bit, the answer on their plain copies."""
    want = _answer(entry, lambda a: _plain(make(a)), x)
    got = _answer(entry, make, x)
    _assert_same_bits(got, want, entry)
    return got


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("entry", ENTRY_POINTS)
def test_each_kind_of_array_gives_the_plain_answer(entry, kind, dtype):
    _check_same_as_plain(entry, KINDS[kind], _inputs(40, dtype))


def _arrays_of(answer):
    """The arrays of an answer: a dict's values, a tuple's items, or the array itself."""
    if isinstance(answer, dict):
        return list(answer.values())
    return list(answer) if isinstance(answer, tuple) else [answer]


@pytest.mark.parametrize("kind", [k for k in KINDS if k != "list"])
@pytest.mark.parametrize("entry", ENTRY_POINTS)
def test_empty_inputs_give_empty_answers_of_the_same_dtypes(entry, kind):
    """(0, 3) rays and points (and a mesh of no triangles): empty answers, of the dtypes and
    trailing shapes of a non-empty call. (A Python list of no rows cannot say its shape.)"""
    full = _answer(entry, np.ascontiguousarray, _inputs(5))
    empty = _inputs(0)
    empty.vertices, empty.faces = empty.vertices[:0], empty.faces[:0]
    empty.attribute = empty.attribute[:0]
    got = _arrays_of(_check_same_as_plain(entry, KINDS[kind], empty))
    assert len(got) == len(_arrays_of(full)), entry
    for g, f in zip(got, _arrays_of(full)):
        assert g.dtype == f.dtype and g.shape == (0,) + f.shape[1:], entry


@pytest.mark.parametrize("seed", range(12))
def test_random_shapes_and_kinds_give_the_plain_answer(seed):
    """Random row counts (0 included), dtypes, bounds (none, a number, an array), masks and a
    kind drawn for each argument on its own."""
    rng = np.random.default_rng(seed)
    for entry in ENTRY_POINTS:
        rows = int(rng.choice([0, 1, 2, 3, int(rng.integers(4, 300))]))
        dtype = [np.float32, np.float64][rng.integers(2)]
        faces_dtype = [np.int64, np.int32, np.uint32, np.uint16][rng.integers(4)]
        x = _inputs(rows, dtype, seed=seed, faces_dtype=faces_dtype)
        x.tmin = [None, 0.05, x.tmin][rng.integers(3)]
        x.tmax = [None, 2.5, x.tmax][rng.integers(3)]
        x.mask = [None, 1, x.mask, x.mask.astype(np.int64)][rng.integers(4)]
        draws = rng.integers(0, 2**32)
        # A Python list of no rows cannot say its shape (N, 3); it is refused as (0,).
        kinds = [KINDS[k] for k in KINDS if rows or k != "list"]

        def make_kinds():
            picks = np.random.default_rng(draws)
            return lambda a: kinds[picks.integers(len(kinds))](a)

        make, same_picks = make_kinds(), make_kinds()
        want = _answer(entry, lambda a: _plain(same_picks(a)), x)
        _assert_same_bits(_answer(entry, make, x), want, f"{entry}, seed {seed}")


# -- Refusals -------------------------------------------------------------------------------

def _refused(a):
    """Arrays of the right shape that no float or index argument accepts."""
    return {
        "complex": a.astype(np.complex64),
        "bool": a.astype(bool),
        "object": a.astype(object),
        "string": a.astype(str),
        "structured": np.zeros(a.shape, [("x", np.float32)]),
        "datetime": np.zeros(a.shape, "datetime64[s]"),
    }


FLOAT_ARGUMENTS = {
    "origins": lambda x, bad: BVH.intersect(bad, x.d),
    "directions": lambda x, bad: GRID.occluded(x.o, bad),
    "tmin": lambda x, bad: SCENE.count(x.o, x.d, tmin=bad),
    "tmax": lambda x, bad: BVH.intersect_all(x.o, x.d, tmax=bad),
    "points": lambda x, bad: BVH.closest_point(bad),
    "vertices": lambda x, bad: hbv.Mesh(bad, x.faces),
    "transform": lambda x, bad: _scene().set_transform(0, bad),
}

INDEX_ARGUMENTS = {
    "faces": lambda x, bad: hbv.Mesh(x.vertices, bad),
    "mask": lambda x, bad: SCENE.contains(x.points, mask=bad),
}


def _assert_refused(call, name):
    try:
        call()
    except (TypeError, ValueError) as e:
        assert name in str(e), f"{name}: {e}"
    except BaseException as e:
        pytest.fail(f"{name}: {type(e).__name__}: {e}")
    else:
        pytest.fail(f"{name}: accepted")


@pytest.mark.parametrize("argument", list(FLOAT_ARGUMENTS) + list(INDEX_ARGUMENTS))
def test_unreadable_arrays_are_refused_naming_the_argument(argument):
    x = _inputs(6)
    call = {**FLOAT_ARGUMENTS, **INDEX_ARGUMENTS}[argument]
    good = getattr(x, {"origins": "o", "directions": "d"}.get(argument, argument))
    bad_values = dict(_refused(good))
    if argument in INDEX_ARGUMENTS:
        bad_values["float"] = good.astype(np.float64)
        bad_values["negative"] = -1 - good.astype(np.int64)
    bad_values["too many axes"] = good[..., None]
    if argument not in ("tmin", "tmax", "mask"):  # one number is a bound or mask for every row
        bad_values["zero axes"] = good.ravel()[0]
    for bad in bad_values.values():
        for kind in (np.ascontiguousarray, _misaligned, _reversed):
            readable = np.ndim(bad) and bad.dtype.kind not in "OUS"
            _assert_refused(lambda: call(x, kind(bad) if readable else bad), argument)


def test_misaligned_float32_rays_of_a_dask_chunk():
    """The case that panicked: float32 rays at an odd offset of a buffer."""
    o, d = random_rays(100, seed=3)
    buffer = bytearray(1) + o.astype(np.float32).tobytes() + d.astype(np.float32).tobytes()
    origins = np.frombuffer(buffer, np.float32, count=300, offset=1).reshape(100, 3)
    directions = np.frombuffer(buffer, np.float32, count=300, offset=1201).reshape(100, 3)
    assert not origins.flags.aligned and origins.flags.c_contiguous
    want = BVH.intersect(o.astype(np.float32), d.astype(np.float32))
    _assert_same_bits(BVH.intersect(origins, directions), want, "intersect")
    assert want["hit"].any()


def test_rows_that_overlap_or_repeat_give_the_plain_answer():
    """Rows one item apart (overlapping), zero items apart (`np.broadcast_to`, one origin for
    every ray) and a single row with any stride: read as NumPy's copy, the plain answer."""
    x = _inputs(50)
    buffer = np.random.default_rng(3).uniform(-1.5, 1.5, 60)
    one_origin = np.broadcast_to(x.o[0], x.o.shape)
    shapes = {
        "overlapping": np.lib.stride_tricks.as_strided(buffer, (50, 3), (8, 8), writeable=False),
        "broadcast": one_origin,
        "one_row": np.lib.stride_tricks.as_strided(buffer, (1, 3), (800, 8), writeable=False),
    }
    for name, origins in shapes.items():
        directions = x.d[: len(origins)]
        for query in (BVH.intersect, BVH.occluded, GRID.count, SCENE.intersect):
            got, want = query(origins, directions), query(np.array(origins), directions)
            _assert_same_bits(got, want, f"{query.__name__}, {name}")
        _assert_same_bits(BVH.contains(origins), BVH.contains(np.array(origins)), name)


def test_numpy_scalars_are_one_value_for_every_row():
    """`mask=np.uint32(1)`, `tmin=np.float32(0.05)` and 0-d arrays mean what Python's numbers
    mean; a NumPy bool or float mask is refused as a Python one is."""
    x = _inputs(30)
    want = SCENE.intersect(x.o, x.d, tmin=0.05, tmax=2.5, mask=1)
    for tmin, tmax, mask in [(np.float32(0.05), np.float64(2.5), np.uint32(1)),
                             (np.array(0.05), np.array(2.5, ">f8"), np.array(1, np.int8))]:
        got = SCENE.intersect(x.o, x.d, tmin=tmin, tmax=tmax, mask=mask)
        _assert_same_bits(got, want, "intersect")
    for bad in (np.True_, np.float32(1.0), np.array(-1)):
        _assert_refused(lambda: SCENE.contains(x.points, mask=bad), "mask")


def test_arguments_that_change_while_they_are_read():
    """Arrays are read from views no other code holds: a bound whose conversion retypes the
    origins (shape (N, 3) float32 becomes (N, 1) of 12-byte records) changes nothing; an
    ndarray subclass whose own view has another shape, and an object NumPy reads as two
    shapes, are refused or read once, never a panic."""
    x = _inputs(20, np.float32)
    want = BVH.intersect(x.o, x.d, tmin=0.01)
    origins = x.o.copy()

    class Retyping:
        def __float__(self):
            origins.dtype = "V12"
            return 0.01

    got = _answer("BVH.intersect", lambda a: a, SimpleNamespace(
        o=origins, d=x.d, tmin=Retyping(), tmax=None))
    _assert_same_bits(got, want, "intersect")

    class OtherView(np.ndarray):
        def view(self, *args, **kwargs):
            return np.zeros(5, np.float32)

    lying = x.o.view(OtherView)
    _assert_refused(lambda: BVH.occluded(lying, x.d), "origins")

    class TwoShapes:
        calls = 0

        def __array__(self, dtype=None, copy=None):
            TwoShapes.calls += 1
            return _shifted(0.5) if TwoShapes.calls == 1 else np.eye(4)[:2]

    scene = _scene()
    scene.set_transform(1, TwoShapes())
    reference = _scene()
    reference.set_transform(1, _shifted(0.5))
    _assert_same_bits(scene.intersect(x.o, x.d), reference.intersect(x.o, x.d), "intersect")


def _byte_kinds(data):
    """The bytes of a file as a worker may hold them."""
    arr = np.frombuffer(data, np.uint8)
    return {
        "bytes": data,
        "bytearray": bytearray(data),
        "memoryview": memoryview(data),
        "misaligned array": _misaligned(arr),
        "read-only array": _read_only(arr),
        "strided array": _strided(arr),
        "reversed array": _reversed(arr),
        "int8 array": arr.view(np.int8),
    }


@pytest.mark.parametrize("what", ["BVH", "Scene"])
def test_pickled_bytes_load_from_any_byte_array(what, tmp_path):
    """The `.hbv` bytes a pickle carries (and a Dask scatter may hand over as a buffer) load
    from bytes, bytearrays, memoryviews and uint8 arrays of every kind, to the same answers;
    anything else is refused naming `data`."""
    x = _inputs(40)
    if what == "BVH":
        structure = BVH
        BVH.save(tmp_path / "tree.hbv")  # a loaded tree pickles as its file's bytes
        load, data = hbv._hbv._bvh_from_bytes, (tmp_path / "tree.hbv").read_bytes()
    else:
        structure = SCENE
        load, data = hbv._hbv._scene_from_bytes, SCENE.__reduce__()[1][0]
    want = structure.intersect(x.o, x.d)
    for kind, given in _byte_kinds(data).items():
        _assert_same_bits(load(given).intersect(x.o, x.d), want, f"{what} from {kind}")
    arr = np.frombuffer(data, np.uint8)
    for bad in (arr.astype(np.float32), arr[: len(arr) // 4 * 4].reshape(-1, 4), "text", 3):
        _assert_refused(lambda: load(bad), "data")
    with pytest.raises(ValueError):
        load(arr[:-1])
