"""Hypothesis strategies for bad (and good) inputs, drawn as small printable recipes.

A recipe is a tuple of plain values (kind, size, seed, dtype, ...) so the input that broke
a call can be logged before the call and rebuilt from the log after a crash; ``build``
turns a recipe into the numpy array or object the entry point receives.
"""

from __future__ import annotations

import numpy as np
from hypothesis import strategies as st

NAN, INF = float("nan"), float("inf")

# Point-cloud recipes: mostly valid (N, 3) float64 so the calls reach the algorithms, with
# every class of bad input the reliability issue lists mixed in.
_KINDS = ["wavy"] * 4 + ["box", "plane", "sphere", "line", "identical", "two_points", "corner"]
_SIZES = [0, 1, 2, 3, 4, 5, 7, 12, 50, 300, 300, 1500]
_SCALES = [0.1] * 6 + [1e-9, 1e-30, 1.0, 1e6, 1e30, 1e300]
_CORRUPT = ["none"] * 6 + ["nan_one", "inf_one", "nan_all", "nan_half", "huge_one"]
_DTYPES = ["f8"] * 8 + ["f4", "f4", "i8", "u1", "?", "c16", "O", "U4", ">f8", "f2"]
_SHAPES = ["n3"] * 10 + ["n2", "n4", "3n", "flat", "n31", "scalar", "list", "none", "str"]
_LAYOUTS = ["C"] * 4 + ["F", "strided", "readonly"]


class Param:
    """A parameter's strategy with its typical values: a case draws at most two parameters
    wild (every bad value) and the rest typical, so calls reach the algorithms instead of
    stopping at the first argument check."""

    def __init__(self, wild: st.SearchStrategy, typical: st.SearchStrategy):
        self.wild, self.typical = wild, typical


def cases(**params) -> st.SearchStrategy:
    keys = sorted(k for k, v in params.items() if isinstance(v, Param))

    def draw(wild_keys):
        return st.fixed_dictionaries({k: (v.wild if k in wild_keys else v.typical) if isinstance(v, Param) else v
                                      for k, v in params.items()})
    return st.sets(st.sampled_from(keys), max_size=2).flatmap(draw) if keys else st.fixed_dictionaries(params)


_AXES = ["none", "none", "scale", "corrupt", "dtype", "shape", "layout"]


def clouds(max_size: int | None = None) -> Param:
    sizes = [s for s in _SIZES if max_size is None or s <= max_size]

    def one_bad_axis(axis):
        pick = lambda name, values, default: st.sampled_from(values) if axis == name else st.just(default)  # noqa: E731
        return st.tuples(st.just("cloud"), st.sampled_from(_KINDS), st.sampled_from(sizes), st.integers(0, 2**16),
                         pick("scale", _SCALES, 0.1), pick("corrupt", _CORRUPT, "none"), pick("dtype", _DTYPES, "f8"),
                         pick("shape", _SHAPES, "n3"), pick("layout", _LAYOUTS, "C"))
    return Param(st.sampled_from(_AXES).flatmap(one_bad_axis), good_clouds(max_size))


def good_clouds(max_size: int | None = None) -> st.SearchStrategy:
    """Finite (N, 3) float64 clouds of every geometry (degenerate ones included)."""
    sizes = [s for s in _SIZES if max_size is None or s <= max_size]
    return st.tuples(st.just("cloud"), st.sampled_from(_KINDS), st.sampled_from(sizes),
                     st.integers(0, 2**16), st.sampled_from([0.1, 0.1, 1e-3, 1.0]), st.just("none"),
                     st.just("f8"), st.just("n3"), st.sampled_from(_LAYOUTS))


def _geometry(kind: str, n: int, rng: np.random.Generator) -> np.ndarray:
    u, v = rng.uniform(-1, 1, (2, n))
    if kind == "wavy":
        return np.c_[u, v, 0.1 * np.sin(3 * u) * np.cos(2 * v) + 4]
    if kind == "box":
        return rng.uniform(-1, 1, (n, 3)) + (0, 0, 4)
    if kind == "plane":
        return np.c_[u, v, 0.3 * u + 4]
    if kind == "sphere":
        d = rng.normal(size=(n, 3))
        return d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12) + (0, 0, 4)
    if kind == "line":
        return np.outer(u, (1.0, 2.0, 3.0)) + (0, 0, 4)
    if kind == "identical":
        return np.tile((0.2, -0.1, 4.0), (n, 1))
    if kind == "two_points":
        return np.where((np.arange(n) % 2)[:, None] == 0, (0.0, 0.0, 4.0), (1.0, 0.0, 4.0))
    # corner: three orthogonal faces, well conditioned for every registration metric
    face = np.arange(n) % 3
    p = np.c_[u, v, np.zeros(n)] + 1
    p[face == 1] = p[face == 1][:, [2, 0, 1]]
    p[face == 2] = p[face == 2][:, [1, 2, 0]]
    return p


def _corrupt(p: np.ndarray, how: str, rng: np.random.Generator) -> np.ndarray:
    if p.size == 0 or how == "none":
        return p
    i = rng.integers(len(p))
    if how == "nan_one":
        p[i, rng.integers(3)] = NAN
    elif how == "inf_one":
        p[i, rng.integers(3)] = -INF
    elif how == "nan_all":
        p[:] = NAN
    elif how == "nan_half":
        p[::2] = NAN
    elif how == "huge_one":
        p[i] = 1e30
    return p


def _reshape(p: np.ndarray, shape: str):
    return {"n3": lambda: p, "n2": lambda: p[:, :2], "n4": lambda: np.c_[p, np.ones(len(p))],
            "3n": lambda: p.T, "flat": lambda: p.ravel(), "n31": lambda: p[:, :, None],
            "scalar": lambda: np.float64(1.0), "list": lambda: p.tolist(), "none": lambda: None,
            "str": lambda: "points"}[shape]()


def _retype(a, dtype: str):
    if not isinstance(a, np.ndarray):
        return a
    if dtype == "O":
        return a.astype(object)
    if dtype == "U4":
        return a.astype("U4")
    with np.errstate(all="ignore"):
        return a.astype(dtype)


def _relayout(a, layout: str):
    if not isinstance(a, np.ndarray) or a.ndim == 0:
        return a
    if layout == "F":
        return np.asfortranarray(a)
    if layout == "strided":
        return np.repeat(a, 2, axis=0)[::2]
    if layout == "readonly":
        a = a.copy()
        a.setflags(write=False)
    return a


def build(recipe):
    """Rebuilds the input a recipe describes (recipes nest inside tuples and dicts)."""
    if isinstance(recipe, dict):
        return {k: build(v) for k, v in recipe.items()}
    if not (isinstance(recipe, tuple) and recipe and isinstance(recipe[0], str)):
        return recipe
    tag = recipe[0]
    if tag == "cloud":
        _, kind, n, seed, scale, corrupt, dtype, shape, layout = recipe
        rng = np.random.default_rng(seed)
        with np.errstate(all="ignore"):
            p = _corrupt(_geometry(kind, n, rng) * scale, corrupt, rng)
        return _relayout(_retype(_reshape(p, shape), dtype), layout)
    if tag == "like":  # an array shaped like another recipe's cloud: normals, weights, colours
        return _like(*recipe[1:])
    if tag == "transform":
        return _transform(*recipe[1:])
    if tag == "raw":
        return recipe[1]
    return recipe


def _like(of, what: str, seed: int):
    base = build(of)
    n = len(base) if isinstance(base, np.ndarray) and base.ndim >= 1 else 3
    rng = np.random.default_rng(seed)
    d = rng.normal(size=(n, 3))
    unit = d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)
    return {"unit": lambda: unit, "zero": lambda: np.zeros((n, 3)),
            "nan": lambda: np.where(np.arange(n)[:, None] == 0, NAN, unit),
            "short": lambda: unit[: max(n - 1, 0)], "long": lambda: np.r_[unit, unit[:1]],
            "scaled": lambda: unit * 7.0, "weights": lambda: rng.uniform(0, 1, n),
            "neg_weights": lambda: -rng.uniform(0, 1, n), "colors_u8": lambda: rng.integers(0, 255, (n, 3)).astype(np.uint8),
            "colors_f": lambda: rng.uniform(0, 1, (n, 3)), "colors_c": lambda: unit.astype(complex),
            "strings": lambda: unit.astype("U3"), "int_idx": lambda: rng.integers(-2, n + 2, n),
            }[what]()


_TRANSFORMS = ["identity", "small", "small", "small", "large", "nan", "inf", "scaled", "shear",
               "far", "3x4", "flat16", "complex", "list", "none", "str", "int"]


def transforms(typical: str = "small") -> Param:
    seeds = st.integers(0, 2**16)
    return Param(st.tuples(st.just("transform"), st.sampled_from(_TRANSFORMS), seeds),
                 st.tuples(st.just("transform"), st.just(typical), seeds))


def rigid_from(rng: np.random.Generator, angle: float, shift: float) -> np.ndarray:
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    T = np.eye(4)
    T[:3, :3] = np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K
    T[:3, 3] = rng.uniform(-shift, shift, 3)
    return T


def _transform(kind: str, seed: int):
    rng = np.random.default_rng(seed)
    T = rigid_from(rng, rng.uniform(0, 0.05), 0.02)
    if kind == "identity":
        return np.eye(4)
    if kind == "large":
        return rigid_from(rng, rng.uniform(0, np.pi), 2.0)
    if kind in ("nan", "inf"):
        T[rng.integers(4), rng.integers(4)] = NAN if kind == "nan" else INF
    elif kind == "scaled":
        T[:3, :3] *= 2
    elif kind == "shear":
        T[0, 1] += 0.3
    elif kind == "far":
        T[:3, 3] = 1e30
    elif kind == "3x4":
        return T[:3]
    elif kind == "flat16":
        return T.ravel()
    elif kind == "complex":
        return T.astype(complex) + 1j
    elif kind == "list":
        return T.tolist()
    elif kind == "none":
        return None
    elif kind == "str":
        return "identity"
    elif kind == "int":
        return np.eye(4, dtype=int)
    return T


def numbers(typical, *extra) -> st.SearchStrategy:
    """A parameter: mostly its typical value(s), else zero, negative, NaN, inf, tiny, huge or
    the wrong type."""
    typical = list(typical) if isinstance(typical, (list, tuple)) else [typical]
    bad = [0, -1, NAN, INF, -INF, 1e-300, 1e300, "1", None] + list(extra)
    return Param(st.sampled_from(typical + bad), st.sampled_from(typical))


def counts(typical, *extra) -> st.SearchStrategy:
    """An integer parameter: typical value(s), else 0, -1, huge, a float or the wrong type."""
    typical = list(typical) if isinstance(typical, (list, tuple)) else [typical]
    bad = [0, -1, 1, 2**31, 2**63 - 1, 2**70, 1.5, NAN, "3", None] + list(extra)
    return Param(st.sampled_from(typical + bad), st.sampled_from(typical))


def choice(values, typical=None) -> Param:
    """A categorical parameter (a name, a flag, a kind): the first value is typical."""
    values = list(values)
    return Param(st.sampled_from(values), st.sampled_from(typical if typical is not None else values[:1]))
