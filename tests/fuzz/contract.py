"""The contract every public entry point must keep, whatever it is given.

A call returns a result, returns a failure status, or raises one of the library's
documented exceptions (ValueError or TypeError naming the argument, OSError for files,
RuntimeError for a computation that failed, KeyboardInterrupt for Ctrl-C). A crash or a
hang kills the fuzz process (the parent test reports the logged input); anything else
(IndexError, KeyError, AttributeError, ZeroDivisionError, MemoryError, SystemError, ...)
or a result flagged as a success that holds non-finite numbers breaks the contract.
"""

from __future__ import annotations

import re

import numpy as np

ALLOWED = (ValueError, TypeError, OSError, RuntimeError)

# Attribute names that flag a result as a success, and those that hold its answer.
SUCCESS_FLAGS = ("converged", "success", "found", "valid", "ok")
ANSWERS = ("T_target_source", "T_scene_model", "T_model_camera", "normal", "distance", "center",
           "radius", "q", "motor", "fitness", "inlier_rmse", "rmse", "coverage", "dual")


class ContractError(AssertionError):
    pass


def _numbers(value) -> np.ndarray | None:
    try:
        a = np.asarray(value)
    except Exception:  # noqa: BLE001 - a value numpy cannot hold is not a number
        return None
    return a if a.dtype.kind in "fc" else None


def _flag(result, name: str):
    value = getattr(result, name, None)
    if value is None or callable(value):
        return None
    return np.asarray(value, dtype=bool)


def check_result(result) -> None:
    """A result flagged as a success holds only finite numbers in its answer fields
    (for per-row flags such as IKResult.ok, the rows flagged)."""
    for flag_name in SUCCESS_FLAGS:
        flag = _flag(result, flag_name)
        if flag is None or not flag.any():
            continue
        for field in ANSWERS:
            value = getattr(result, field, None)
            a = _numbers(value) if value is not None and not callable(value) else None
            if a is None:
                continue
            if flag.ndim >= 1 and a.shape[:flag.ndim] == flag.shape:
                a = a[flag]  # per-row flags (IK solutions): only the rows flagged
            if not np.all(np.isfinite(a)):
                raise ContractError(f"result flagged {flag_name} holds non-finite {field}: {value!r}")


def finite(a, what: str = "output") -> None:
    a = np.asarray(a)
    if a.dtype.kind in "fc" and not np.all(np.isfinite(a)):
        raise ContractError(f"{what} holds non-finite values")


def call(fn, *args, **kwargs):
    """Calls fn; documented exceptions pass (returning None), the rest propagate as
    findings, and so does a TypeError that only dumps pybind11's signatures (the library
    names the wrongly typed argument, scanalign.common.arrays.explain_bad_arguments)."""
    try:
        result = fn(*args, **kwargs)
    except ALLOWED as exc:
        if isinstance(exc, TypeError) and re.match(r"[\w.]*\(\): incompatible function arguments", str(exc)):
            STATS["signature_dumps"] += 1  # pybind11 could not say which argument: a finding
            raise ContractError(f"a signature dump instead of a message naming the argument: {exc}") from exc
        STATS["refused"] += 1
        return None
    STATS["returned"] += 1
    check_result(result)
    return result


STATS = {"returned": 0, "refused": 0, "signature_dumps": 0, "truth_checks": 0}
