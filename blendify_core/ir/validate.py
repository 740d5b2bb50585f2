"""Input validation helpers: every check names the argument, what was expected and what was given."""

from __future__ import annotations

import datetime
import inspect
import math
from collections.abc import Iterable, Sequence
from typing import Any, TypeVar

import numpy as np

from blendify_core.errors import InvalidSceneError, describe
from blendify_core.errors import strict_arguments as strict_arguments  # re-exported: the IR's decorator
from blendify_core.typing import AnyArray

_Array = TypeVar("_Array", bound="np.ndarray[Any, Any]")

#: the IR modules' name for :func:`blendify_core.errors.describe` (a short description of a bad value)
_describe = describe


def _unmasked(name: str, value: Any) -> Any:
    """A masked array's data when nothing is masked; InvalidSceneError naming ``name`` when something is
    (``np.asarray`` would drop the mask silently and use the values under it)."""
    if isinstance(value, np.ma.MaskedArray):
        n = int(np.count_nonzero(np.asarray(value.mask)))  # nomask counts 0
        if n:
            raise InvalidSceneError(
                f"{name}: got a masked array with {n} masked value(s); the mask cannot be honoured here, "
                "pass np.ma.filled(array, value) or drop the masked rows"
            )
        return np.asarray(value.data)
    return value


def _check_kind(name: str, raw: AnyArray) -> None:
    """Refuse arrays that are not numbers: dates, durations, strings, objects, complex."""
    if raw.dtype.kind in "mM":
        raise InvalidSceneError(f"{name}: expected numbers, got {raw.dtype} values (dates or durations)")
    if raw.dtype == object or raw.dtype.kind in "USV":
        raise InvalidSceneError(f"{name}: expected a numeric array, got {_describe(raw)}")
    if raw.dtype.kind == "c":
        raise InvalidSceneError(f"{name}: expected real numbers, got complex values")


def raw_array(name: str, value: Any) -> AnyArray:
    """``np.asarray(value)`` for a first look at user input; ragged nested lists and other values numpy
    cannot turn into an array raise InvalidSceneError naming ``name``, as do masked arrays with masked
    values."""
    value = _unmasked(name, value)
    if isinstance(value, np.ndarray):
        return value
    try:
        return np.asarray(value)
    except (ValueError, TypeError) as exc:
        raise InvalidSceneError(f"{name}: expected a numeric array, got {_describe(value)} ({exc})") from None


def frozen(array: _Array) -> _Array:
    """Mark an array read-only (in place) and return it."""
    array.flags.writeable = False
    return array


def as_array(
    name: str,
    value: Any,
    *,
    dtype: Any = np.float64,
    shape: Sequence[int | None] | None = None,
    ndim: int | tuple[int, ...] | None = None,
    finite: bool = True,
    min_value: float | None = None,
    max_value: float | None = None,
    copy: bool = True,
    allow_empty: bool = True,
) -> AnyArray:
    """Convert ``value`` to a read-only array of ``dtype`` and check it.

    ``shape`` may contain ``None`` for "any size" in that dimension.
    """
    if value is None:
        raise InvalidSceneError(f"{name}: expected an array, got None")
    if isinstance(value, (str, bytes)):
        raise InvalidSceneError(f"{name}: expected a numeric array, got {_describe(value)}")
    value = _unmasked(name, value)
    try:
        raw = np.asarray(value)
    except (ValueError, TypeError) as exc:  # ragged nested lists
        raise InvalidSceneError(f"{name}: expected a numeric array, got {_describe(value)} ({exc})") from None
    _check_kind(name, raw)
    if raw.dtype.kind == "b" and np.dtype(dtype).kind != "b":
        raise InvalidSceneError(f"{name}: expected numbers, got a boolean array")
    target = np.dtype(dtype)
    if target.kind in "iu" and raw.dtype.kind == "f":
        if raw.size and (not np.all(np.isfinite(raw)) or np.any(raw != np.round(raw))):
            raise InvalidSceneError(f"{name}: expected integer values, got non-integer floats")
    if ndim is not None:
        allowed = (ndim,) if isinstance(ndim, int) else ndim
        if raw.ndim not in allowed:
            raise InvalidSceneError(
                f"{name}: expected {' or '.join(map(str, allowed))} dimensions, got {_describe(raw)}"
            )
    if shape is not None:
        if raw.ndim != len(shape) or any(s is not None and s != r for s, r in zip(shape, raw.shape)):
            want = "(" + ", ".join("N" if s is None else str(s) for s in shape) + ")"
            raise InvalidSceneError(f"{name}: expected shape {want}, got {_describe(raw)}")
    if not allow_empty and raw.size == 0:
        raise InvalidSceneError(f"{name}: expected a non-empty array, got {_describe(raw)}")
    if target.kind in "iu" and raw.size:
        info = np.iinfo(target)
        if raw.min() < info.min or raw.max() > info.max:
            raise InvalidSceneError(f"{name}: values do not fit in {target}")
    out = np.array(raw, dtype=target, copy=True) if copy else np.asarray(raw, dtype=target)
    if out.dtype.kind == "f" and out.size:
        if finite and not np.all(np.isfinite(out)):
            bad = int(np.count_nonzero(~np.isfinite(out)))
            raise InvalidSceneError(f"{name}: expected finite values, got {bad} NaN or infinite value(s)")
        if min_value is not None and np.nanmin(out) < min_value:
            raise InvalidSceneError(f"{name}: expected values >= {min_value}, got a minimum of {np.nanmin(out):g}")
        if max_value is not None and np.nanmax(out) > max_value:
            raise InvalidSceneError(f"{name}: expected values <= {max_value}, got a maximum of {np.nanmax(out):g}")
    elif out.dtype.kind in "iu" and out.size:
        if min_value is not None and out.min() < min_value:
            raise InvalidSceneError(f"{name}: expected values >= {min_value}, got a minimum of {out.min()}")
        if max_value is not None and out.max() > max_value:
            raise InvalidSceneError(f"{name}: expected values <= {max_value}, got a maximum of {out.max()}")
    return frozen(out)


_NOT_NUMBERS = (str, bytes, bytearray, complex, np.complexfloating, datetime.date, datetime.time, datetime.timedelta)


def as_float(
    name: str,
    value: Any,
    *,
    min_value: float | None = None,
    max_value: float | None = None,
    exclusive_min: bool = False,
    exclusive_max: bool = False,
    finite: bool = True,
    unit: str = "",
) -> float:
    """Check a real scalar within an optional range. Booleans, strings, bytes, complex numbers, dates and
    durations are refused (``float("1.5")`` would accept a string); NaN is always refused, infinities
    unless ``finite=False``. ``unit`` is named in a range error ("rad": with the conversion from degrees)."""
    if isinstance(value, (bool, np.bool_, np.datetime64, np.timedelta64) + _NOT_NUMBERS) or value is None:
        raise InvalidSceneError(f"{name}: expected a real number, got {_describe(value)}")
    value = _unmasked(name, value)  # a masked scalar would become NaN with a numpy warning
    if isinstance(value, np.ndarray):  # float() of a 1-element array is deprecated in numpy
        if value.size != 1 or value.dtype.kind not in "iuf":
            raise InvalidSceneError(f"{name}: expected a real number, got {_describe(value)}")
        value = value.reshape(-1)[0]
    try:
        out = float(value)
    except (TypeError, ValueError, OverflowError):
        raise InvalidSceneError(f"{name}: expected a real number, got {_describe(value)}") from None
    if math.isnan(out) or (finite and math.isinf(out)):
        raise InvalidSceneError(f"{name}: expected a finite number, got {out}")
    what = f"{UNIT_NAMES.get(unit, unit)} " if unit else "a value "
    if min_value is not None and (out < min_value or (exclusive_min and out == min_value)):
        op = ">" if exclusive_min else ">="
        raise InvalidSceneError(f"{name}: expected {what}{op} {_bound(min_value)}, got {out:g}")
    if max_value is not None and (out > max_value or (exclusive_max and out == max_value)):
        op = "<" if exclusive_max else "<="
        raise InvalidSceneError(
            f"{name}: expected {what}{op} {_bound(max_value)}, got {out:g}{unit_hint(unit, out, max_value)}"
        )
    return out


#: how a range error names a unit
UNIT_NAMES = {"rad": "radians", "m": "metres", "W": "watts", "nm": "nanometres"}


def _bound(x: float) -> str:
    return "pi" if x == math.pi else ("2 pi" if x == 2 * math.pi else f"{x:g}")


def unit_hint(unit: str, value: float, max_value: float | None) -> str:
    """'; did you mean np.deg2rad(40)?' for a value above a radian range that reads as degrees, else ''."""
    if unit == "rad" and max_value is not None and max_value < value <= 360.0:
        return f"; did you mean np.deg2rad({value:g})?"
    return ""


def as_int(name: str, value: Any, *, min_value: int | None = None, max_value: int | None = None) -> int:
    """Check an integer scalar within an optional range."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        if isinstance(value, float) and value.is_integer():
            value = int(value)
        else:
            raise InvalidSceneError(f"{name}: expected an integer, got {_describe(value)}")
    out = int(value)
    if min_value is not None and out < min_value:
        raise InvalidSceneError(f"{name}: expected an integer >= {min_value}, got {out}")
    if max_value is not None and out > max_value:
        raise InvalidSceneError(f"{name}: expected an integer <= {max_value}, got {out}")
    return out


def as_bool(name: str, value: Any) -> bool:
    """The one boolean rule: ``True``/``False``, a numpy bool, or the integers 0 and 1. Strings (``"no"``,
    ``"False"``), other numbers, None and everything else raise InvalidSceneError naming ``name``."""
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)) and value in (0, 1):
        return bool(value)
    raise InvalidSceneError(f"{name}: expected True or False (or 0 / 1), got {_describe(value)}")


def as_choice(name: str, value: Any, choices: Iterable[str], *, case_insensitive: bool = True) -> str:
    options = list(choices)
    if not isinstance(value, str):
        raise InvalidSceneError(f"{name}: expected one of {options}, got {_describe(value)}")
    key = value.lower() if case_insensitive else value
    for option in options:
        if (option.lower() if case_insensitive else option) == key:
            return option
    raise InvalidSceneError(f"{name}: expected one of {options}, got {value!r}")


def as_vector(name: str, value: Any, size: int, **kwargs: Any) -> AnyArray:
    return as_array(name, value, shape=(size,), **kwargs)


def check_tag(name: str, value: Any) -> str:
    if not isinstance(value, str) or not value or value != value.strip():
        raise InvalidSceneError(
            f"{name}: expected a non-empty string without surrounding spaces, got {_describe(value)}"
        )
    return value


def reject_unknown(where: str, kwargs: dict[str, Any], allowed: Iterable[str] = ()) -> None:
    unknown = sorted(set(kwargs) - set(allowed))
    if unknown:
        raise InvalidSceneError(f"{where}: unknown keyword argument(s) {unknown}")


_C = TypeVar("_C", bound=type)


def strict_api(cls: _C) -> _C:
    """Class decorator: :func:`strict_arguments` on ``__init__`` and on every public method, static
    method and class method the class defines itself (base classes that call it from
    ``__init_subclass__`` make every subclass strict too). The one place the public API's keyword
    checking comes from."""
    for name, attr in list(vars(cls).items()):
        if name.startswith("_") and name != "__init__":
            continue
        if isinstance(attr, staticmethod):
            setattr(cls, name, staticmethod(strict_arguments(attr.__func__)))
        elif isinstance(attr, classmethod):
            setattr(cls, name, classmethod(strict_arguments(attr.__func__)))
        elif inspect.isfunction(attr):
            setattr(cls, name, strict_arguments(attr))
    return cls
