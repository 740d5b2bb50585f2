"""Parameter declarations: every material and light parameter is declared once, as a :class:`Param`.

A declaration gives the name, the kind (float, int, bool, color, vec3, choice, texture, normal_map or a
custom rule), the default, the valid range with its open or closed ends, the unit, a one-line doc and,
where Blender silently clamps values that blendify users pass (``coat_ior`` below 1), a :class:`Clamp`.
It drives everything else:

- validation: :meth:`Param.check`, one function per kind, implementing the one policy of
  ``docs/conventions.md`` ("Validation policy");
- attributes: :class:`ParamAttribute` reads and writes ``obj.<name>`` with validation;
- constructors: :func:`build_signature` / :func:`bind_arguments` give a class its ``__init__`` and
  ``__signature__`` from the declaration (``inspect.signature`` sees ordinary named parameters);
- the scene-file schema: :func:`encode_params` / :func:`decode_params` walk the declaration;
- ``docs/parameters.md``: :mod:`blendify_core.ir.paramdocs` renders the declarations as tables.
"""

from __future__ import annotations

import inspect
import math
import os
import warnings
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from blendify_core.errors import InvalidSceneError
from blendify_core.errors import describe as _describe
from blendify_core.ir.colors import NormalMap, TextureMap
from blendify_core.ir.validate import UNIT_NAMES, as_array, as_bool, as_choice, as_float, as_int, strict_api, unit_hint
from blendify_core.typing import AnyArray

__all__ = [
    "KINDS",
    "REQUIRED",
    "BlenderClampWarning",
    "Clamp",
    "Param",
    "ParamAttribute",
    "Signature",
    "Declared",
    "POSE",
    "TAG",
    "build_signature",
    "bind_arguments",
    "encode_params",
    "decode_params",
]

#: The kinds a parameter can have.
KINDS = ("float", "int", "bool", "color", "vec3", "choice", "texture", "normal_map", "custom")

_PACKAGE_DIR = str(Path(__file__).resolve().parents[1])


class _Required:
    """The default of a parameter that has none (it must be given)."""

    def __repr__(self) -> str:
        return "REQUIRED"


REQUIRED: Any = _Required()

#: the largest light strength / emission strength accepted. Engines compute radiance in float32 (largest
#: value 3.4e38): Cycles rendered emission 1e38 as inf and 1e39 black, Mitsuba NaN, a 1e308 W point light
#: NaN / black. 1e30 renders finite in all three (the hard case ``huge_emission_1e30``; a 1e30 W point light
#: of radius 0.01 m too) and leaves 8 orders of magnitude for the geometry factors (1 / radius^2, 1 / area).
MAX_EMISSION = 1e30
_EMISSION_NOTE = "render engines compute in float32: larger strengths overflow to inf or NaN"


class BlenderClampWarning(UserWarning):
    """A value inside a declared Blender clamp range was replaced by what Blender renders it as."""


def _num(x: float) -> str:
    """A bound as the docs show it: 1 not 1.0, pi not 3.14159..."""
    if x == math.pi:
        return "pi"
    if x == math.inf:
        return "inf"
    if x == -math.inf:
        return "-inf"
    return f"{x:g}"


@dataclass(frozen=True)
class Clamp:
    """Values in ``[low, high]`` (ends open as flagged) are replaced by ``to`` with a
    :class:`BlenderClampWarning` naming the parameter: Blender renders them as ``to``."""

    low: float
    high: float
    to: float
    low_open: bool = False
    high_open: bool = False

    def __contains__(self, x: object) -> bool:
        if not isinstance(x, float):
            return False
        above = x > self.low or (not self.low_open and x == self.low)
        below = x < self.high or (not self.high_open and x == self.high)
        return above and below

    @property
    def interval(self) -> str:
        return f"{'(' if self.low_open else '['}{_num(self.low)}, {_num(self.high)}{')' if self.high_open else ']'}"

    def __str__(self) -> str:
        return f"{self.interval} -> {_num(self.to)}"


_ANNOTATIONS = {
    "float": "float",
    "int": "int",
    "bool": "bool",
    "color": "Any",
    "vec3": "Any",
    "choice": "str",
    "texture": "TextureMap | None",
    "normal_map": "NormalMap | None",
    "custom": "Any",
}

_TYPE_TEXT = {
    "float": "float",
    "int": "int",
    "bool": "bool",
    "vec3": "(x, y, z) floats",
    "texture": "TextureMap or None",
    "normal_map": "NormalMap or None",
}


@dataclass(frozen=True)
class Param:
    """One declared parameter. ``min_value``/``max_value`` bound the values kept as given (``min_open`` /
    ``max_open`` exclude the bound itself); ``clamps`` list Blender's clamp ranges outside them, whose values
    are replaced with a warning. Anything else outside the range raises InvalidSceneError naming the
    parameter."""

    name: str
    default: Any = REQUIRED
    kind: str = "float"
    min_value: float | None = None
    max_value: float | None = None
    unit: str = ""
    doc: str = ""
    min_open: bool = False
    max_open: bool = False
    clamps: tuple[Clamp, ...] = ()
    #: said after the valid range when a value is outside it (why the range ends there)
    range_note: str = ""
    #: choice: the options (matched case-insensitively, stored as declared)
    choices: tuple[str, ...] = ()
    #: choice: other accepted spellings, (alias, option) pairs (e.g. Blender's "disk" for "circle")
    aliases: tuple[tuple[str, str], ...] = ()
    #: color: the channel counts accepted (lights: RGB only)
    channels: tuple[int, ...] = (3, 4)
    #: color: a 4th value is accepted only when it is 1 and is dropped (the background's RGBA form)
    opaque_alpha: bool = False
    #: None is a valid value (textures: no map; a choice: decided from other inputs)
    nullable: bool = False
    #: float: +-inf is a valid value (NaN never is)
    allow_inf: bool = False
    #: settable only at creation (assigning later raises, naming the parameter)
    fixed: bool = False
    #: stored on the object and readable / settable as an attribute (False: a constructor input only)
    stored: bool = True
    #: which revision a change bumps on positionable objects ("appearance" or "geometry")
    group: str = "appearance"
    #: the type annotation shown by ``inspect.signature`` (derived from the kind when empty)
    annotation: str = ""
    #: custom kind: ``check(obj, name, value) -> value`` and the type shown in the docs
    check_fn: Callable[[Any, str, Any], Any] | None = field(default=None, compare=False, repr=False)
    type_text: str = ""
    #: custom kind: ``encode(obj, value) -> JSON`` when the stored value is not JSON-ready as it is
    encode_fn: Callable[[Any, Any], Any] | None = field(default=None, compare=False, repr=False)

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise TypeError(f"Param {self.name!r}: unknown kind {self.kind!r}")
        if self.kind == "custom" and self.stored and self.check_fn is None:
            raise TypeError(f"Param {self.name!r}: a stored custom parameter needs check_fn")

    # -- description -------------------------------------------------------------------------------
    @property
    def required(self) -> bool:
        return self.default is REQUIRED

    @property
    def signature_annotation(self) -> str:
        if self.annotation:
            return self.annotation
        text = _ANNOTATIONS[self.kind]
        return f"{text} | None" if self.nullable and "None" not in text else text

    @property
    def type_description(self) -> str:
        if self.type_text:
            return self.type_text
        if self.kind == "color":
            counts = " or ".join({3: "RGB", 4: "RGBA"}.get(c, str(c)) for c in self.channels)
            return "RGB (or RGBA with alpha 1)" if self.opaque_alpha else counts
        if self.kind == "choice":
            text = " / ".join(f'"{c}"' for c in self.choices)
            return text + (" or None" if self.nullable else "")
        return _TYPE_TEXT.get(self.kind, self.kind)

    @property
    def has_range(self) -> bool:
        return self.min_value is not None or self.max_value is not None

    def range_text(self) -> str:
        """``[0, 1]``, ``(0, inf)``, ``>= 0`` style text of the valid range ('' when unbounded)."""
        if not self.has_range:
            return ""
        lo = _num(self.min_value) if self.min_value is not None else "-inf"
        hi = _num(self.max_value) if self.max_value is not None else "inf"
        lo_b = "(" if (self.min_open or self.min_value is None) else "["
        hi_b = ")" if (self.max_open or self.max_value is None) else "]"
        return f"{lo_b}{lo}, {hi}{hi_b}"

    def clamp_text(self) -> str:
        return ", ".join(str(c) for c in self.clamps)

    # -- validation --------------------------------------------------------------------------------
    def in_range(self, x: float) -> bool:
        if self.min_value is not None and (x < self.min_value or (self.min_open and x == self.min_value)):
            return False
        if self.max_value is not None and (x > self.max_value or (self.max_open and x == self.max_value)):
            return False
        return True

    def check(self, value: Any, obj: Any = None, name: str | None = None) -> Any:
        """The validated (and possibly clamped) value, or InvalidSceneError naming the parameter."""
        label = name or self.name
        if value is None and self.nullable:
            return None
        return _CHECKS[self.kind](self, label, value, obj)


# ---------------------------------------------------------------------------------------------------
# one validation function per kind
# ---------------------------------------------------------------------------------------------------


def emission_param(name: str, default: Any, doc: str, unit: str = "") -> Param:
    """A light power or emission strength: [0, MAX_EMISSION] (engines overflow beyond)."""
    return Param(name, default, "float", 0.0, MAX_EMISSION, unit=unit, doc=doc, range_note=_EMISSION_NOTE)


def _out_of_range(p: Param, label: str, shown: str, value: float | None = None) -> InvalidSceneError:
    extra = f" (Blender's clamp ranges {p.clamp_text()} are accepted with a warning)" if p.clamps else ""
    what = f"{UNIT_NAMES.get(p.unit, p.unit)} in" if p.unit in UNIT_NAMES else "a value in"
    hint = "" if value is None else unit_hint(p.unit, value, p.max_value)
    note = f" ({p.range_note})" if p.range_note else ""
    return InvalidSceneError(f"{label}: expected {what} {p.range_text()}{extra}{note}, got {shown}{hint}")


def _warn_clamped(label: str, value: float, clamp: Clamp) -> None:
    # the warning points at the first caller outside blendify_core (the user's line)
    frame = inspect.currentframe()
    level = 1
    while frame is not None and os.path.abspath(frame.f_code.co_filename).startswith(_PACKAGE_DIR):
        frame = frame.f_back
        level += 1
    warnings.warn(
        f"{label}: {value:g} is in Blender's clamp range {clamp.interval}; clamped to {_num(clamp.to)}, "
        "which is how Blender renders it",
        BlenderClampWarning,
        stacklevel=level,
    )


def _check_float(p: Param, label: str, value: Any, obj: Any) -> float:
    v = as_float(label, value, finite=not p.allow_inf)
    if p.in_range(v):
        return v
    for clamp in p.clamps:
        if v in clamp:
            _warn_clamped(label, v, clamp)
            return float(clamp.to)
    raise _out_of_range(p, label, f"{v:g}", v)


def _check_int(p: Param, label: str, value: Any, obj: Any) -> int:
    v = as_int(label, value)
    if not p.in_range(float(v)):
        raise _out_of_range(p, label, str(v))
    return v


def _check_bool(p: Param, label: str, value: Any, obj: Any) -> bool:
    return as_bool(label, value)


def _check_color(p: Param, label: str, value: Any, obj: Any) -> tuple[float, ...]:
    arr = as_array(label, value, ndim=1, min_value=p.min_value, max_value=p.max_value)
    if arr.shape[0] not in p.channels:
        want = " or ".join(f"{c} ({ {3: 'RGB', 4: 'RGBA'}.get(c, 'values') })" for c in p.channels)
        raise InvalidSceneError(f"{label}: expected {want} values, got {arr.shape[0]}")
    if p.opaque_alpha and arr.shape[0] == 4:
        if arr[3] != 1.0:
            raise InvalidSceneError(
                f"{label}: expected 3 (RGB) values (a 4th, alpha, only as 1: it cannot be honoured), "
                f"got alpha {arr[3]:g}"
            )
        arr = arr[:3]
    return tuple(float(x) for x in arr)


def _check_vec3(p: Param, label: str, value: Any, obj: Any) -> tuple[float, ...]:
    arr = as_array(label, value, shape=(3,), min_value=p.min_value, max_value=p.max_value)
    return tuple(float(x) for x in arr)


def _check_choice(p: Param, label: str, value: Any, obj: Any) -> str:
    if isinstance(value, str):
        value = next((option for alias, option in p.aliases if alias == value.lower()), value)
    return as_choice(label, value, p.choices)


def _check_texture(p: Param, label: str, value: Any, obj: Any) -> TextureMap | None:
    if value is not None and (not isinstance(value, TextureMap) or isinstance(value, NormalMap)):
        raise InvalidSceneError(f"{label}: expected a TextureMap or None, got {_describe(value)}")
    return value


def _check_normal_map(p: Param, label: str, value: Any, obj: Any) -> NormalMap | None:
    if value is not None and not isinstance(value, NormalMap):
        raise InvalidSceneError(f"{label}: expected a NormalMap or None, got {_describe(value)}")
    return value


def _check_custom(p: Param, label: str, value: Any, obj: Any) -> Any:
    if p.check_fn is None:  # pragma: no cover - refused by Param.__post_init__
        raise TypeError(f"Param {p.name!r}: a custom parameter needs check_fn")
    return p.check_fn(obj, label, value)


_CHECKS: dict[str, Callable[[Param, str, Any, Any], Any]] = {
    "float": _check_float,
    "int": _check_int,
    "bool": _check_bool,
    "color": _check_color,
    "vec3": _check_vec3,
    "choice": _check_choice,
    "texture": _check_texture,
    "normal_map": _check_normal_map,
    "custom": _check_custom,
}


# ---------------------------------------------------------------------------------------------------
# attributes
# ---------------------------------------------------------------------------------------------------


class ParamAttribute:
    """``obj.<name>``: reads the stored value, validates every assignment through the owner's
    ``_set_param`` (which stores it and records the change)."""

    def __init__(self, name: str, doc: str = "") -> None:
        self.name = name
        self.__doc__ = doc

    def __get__(self, obj: Any, owner: type | None = None) -> Any:
        if obj is None:
            return self
        try:
            return obj.__dict__["_values"][self.name]
        except KeyError:
            raise AttributeError(f"{type(obj).__name__} has no attribute {self.name!r} yet") from None

    def __set__(self, obj: Any, value: Any) -> None:
        obj._set_param(type(obj)._param_index[self.name], value)


def install_attributes(cls: type, params: Iterable[Param]) -> None:
    """Give ``cls`` a :class:`ParamAttribute` for every stored parameter."""
    for p in params:
        if p.stored:
            doc = p.doc + (f" ({p.unit})" if p.unit else "")
            setattr(cls, p.name, ParamAttribute(p.name, doc))


# ---------------------------------------------------------------------------------------------------
# constructor signatures
# ---------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Signature:
    """The constructor signature of a class, from its declaration: ``names`` are the named parameters
    in order (None: every declared constructor input, in declaration order); every other declared input
    is accepted by keyword through ``**var_keyword`` (or refused when ``var_keyword`` is None)."""

    names: tuple[str, ...] | None = None
    var_keyword: str | None = "kwargs"


def build_signature(
    params: Iterable[Param], spec: Signature, *, self_param: bool = False, returns: Any = inspect.Signature.empty
) -> inspect.Signature:
    by_name = {p.name: p for p in params}
    names = tuple(by_name) if spec.names is None else spec.names
    out = []
    if self_param:
        out.append(inspect.Parameter("self", inspect.Parameter.POSITIONAL_OR_KEYWORD))
    for n in names:
        p = by_name[n]
        out.append(
            inspect.Parameter(
                n,
                inspect.Parameter.POSITIONAL_OR_KEYWORD,
                default=inspect.Parameter.empty if p.required else p.default,
                annotation=p.signature_annotation,
            )
        )
    if spec.var_keyword:
        out.append(inspect.Parameter(spec.var_keyword, inspect.Parameter.VAR_KEYWORD, annotation="Any"))
    return inspect.Signature(out, return_annotation=returns)


def bind_arguments(
    where: str,
    params: Iterable[Param],
    positional: tuple[str, ...],
    var_keyword: bool,
    args: tuple[Any, ...],
    kwargs: Mapping[str, Any],
) -> dict[str, Any]:
    """Every declared input of a call by name (defaults filled in), or InvalidSceneError naming the
    unknown, surplus, repeated or missing argument. ``positional`` are the signature's named parameters;
    with ``var_keyword`` every other declared input is accepted by keyword."""
    by_name = {p.name: p for p in params}
    if len(args) > len(positional):
        raise InvalidSceneError(
            f"{where}: takes at most {len(positional)} positional argument(s), got {len(args)}; "
            "pass the others by keyword"
        )
    given = dict(zip(positional, args))
    for key, value in kwargs.items():
        if key in given:
            raise InvalidSceneError(f"{where}: got multiple values for argument {key!r}")
        given[key] = value
    allowed = set(by_name) if var_keyword else set(positional)
    unknown = sorted(set(given) - allowed)
    if unknown:
        raise InvalidSceneError(f"{where}: unknown keyword argument(s) {unknown}")
    out = {}
    for name, p in by_name.items():
        if name in given:
            out[name] = given[name]
        elif p.required:
            raise InvalidSceneError(f"{where}: missing required argument {name!r}")
        else:
            out[name] = p.default
    return out


def with_defaults(params: Iterable[Param], defaults: Mapping[str, Any]) -> tuple[Param, ...]:
    """The declaration with some defaults replaced (presets such as MetalMaterial)."""
    params = tuple(params)
    unknown = set(defaults) - {p.name for p in params}
    if unknown:
        raise TypeError(f"preset names undeclared parameter(s) {sorted(unknown)}")
    return tuple(replace(p, default=defaults[p.name]) if p.name in defaults else p for p in params)


# ---------------------------------------------------------------------------------------------------
# pose and tag: constructor inputs of lights and renderables (declared once, here)
# ---------------------------------------------------------------------------------------------------


def _as_given(obj: Any, name: str, value: Any) -> Any:
    return value


ROTATION_MODE = Param(
    "rotation_mode",
    "quaternionWXYZ",
    "custom",
    stored=False,
    annotation="str",
    type_text="str",
    check_fn=_as_given,
    doc="How ``rotation`` is given (docs/conventions.md, 'World and poses')",
)
ROTATION = Param(
    "rotation",
    None,
    "custom",
    stored=False,
    annotation="Any",
    type_text="per rotation_mode",
    check_fn=_as_given,
    doc="The rotation (None: identity)",
)
TRANSLATION = Param(
    "translation",
    (0, 0, 0),
    "custom",
    stored=False,
    annotation="Any",
    type_text="(x, y, z)",
    unit="m",
    check_fn=_as_given,
    doc="World position",
)
TAG = Param(
    "tag",
    None,
    "custom",
    stored=False,
    annotation="str | None",
    type_text="str or None",
    check_fn=_as_given,
    doc="Name in the scene (None: an automatic one)",
)
#: rotation_mode, rotation, translation, in signature order
POSE: tuple[Param, ...] = (ROTATION_MODE, ROTATION, TRANSLATION)


# ---------------------------------------------------------------------------------------------------
# objects built from a declaration
# ---------------------------------------------------------------------------------------------------


def _generated_init(cls: type[Declared]) -> Callable[..., None]:
    positional, var_keyword = cls._positional, cls._signature.var_keyword is not None

    def __init__(self: Declared, *args: Any, **kwargs: Any) -> None:
        where = type(self).__name__
        for name in kwargs:
            if name in type(self)._fixed_params:
                raise type(self)._not_settable(name)
        self._setup(bind_arguments(where, type(self)._declared, positional, var_keyword, args, kwargs))

    __init__.__qualname__ = f"{cls.__qualname__}.__init__"
    __init__.__module__ = cls.__module__
    __init__.__doc__ = f"Build a {cls.__name__} (parameters: docs/parameters.md)."
    __init__.__signature__ = build_signature(cls._declared, cls._signature, self_param=True)  # type: ignore[attr-defined]
    return __init__


class Declared:
    """Base of objects whose parameters are declared as :class:`Param` in ``_declared``.

    A subclass gets, from its declaration: an ``__init__`` with the ``inspect.signature`` of ``_signature``
    (unless it defines its own), a validated attribute per stored parameter, ``_values`` holding them,
    ``parameters()`` and ``parameter_names()``. ``_preset`` replaces inherited defaults (presets declare
    only what they change). ``_setup(inputs)`` receives every declared input by name."""

    _declared: tuple[Param, ...] = ()
    _preset: Mapping[str, Any] = {}
    #: the stored parameters a caller may set (None: every one); the others keep the preset's value and
    #: passing or assigning them raises (DiffuseMaterial: a Lambertian reflector has no metallic)
    _settable: tuple[str, ...] | None = None
    _fixed_params: frozenset[str] = frozenset()
    _signature: Signature = Signature()
    _stored: tuple[Param, ...] = ()
    _param_index: dict[str, Param] = {}
    _positional: tuple[str, ...] = ()
    _values: dict[str, Any]

    if TYPE_CHECKING:  # the real __init__ is generated from the declaration (see __init_subclass__)

        def __init__(self, *args: Any, **kwargs: Any) -> None: ...

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        own = cls.__dict__
        if "_preset" in own:
            cls._declared = with_defaults(cls._declared, cls._preset)
        names = [p.name for p in cls._declared]
        if len(set(names)) != len(names):
            raise TypeError(f"{cls.__name__}: a parameter is declared twice in {names}")
        cls._stored = tuple(p for p in cls._declared if p.stored)
        if cls._settable is not None:
            cls._fixed_params = frozenset(p.name for p in cls._stored if p.name not in cls._settable)
        cls._param_index = {p.name: p for p in cls._declared}
        cls._positional = tuple(names) if cls._signature.names is None else tuple(cls._signature.names)
        missing = [n for n in cls._positional if n not in cls._param_index]
        if missing:
            raise TypeError(f"{cls.__name__}: signature names undeclared parameter(s) {missing}")
        install_attributes(cls, cls._stored)
        if "__init__" not in own:
            cls.__init__ = _generated_init(cls)  # type: ignore[method-assign]
            cls.__signature__ = build_signature(cls._declared, cls._signature)  # type: ignore[attr-defined]
        elif "__signature__" not in own:
            cls.__signature__ = None  # type: ignore[attr-defined]  # inspect reads the class's own __init__
        strict_api(cls)

    def _setup(self, inputs: dict[str, Any]) -> None:
        self._init_values(inputs)

    def _init_values(self, inputs: Mapping[str, Any]) -> None:
        """Validate and store every stored parameter, in declaration order (a later check may read an
        earlier value, e.g. an area light's size reads its shape)."""
        values: dict[str, Any] = {}
        self.__dict__["_values"] = values
        for p in type(self)._stored:
            values[p.name] = p.check(inputs[p.name], self)

    @classmethod
    def _not_settable(cls, name: str) -> InvalidSceneError:
        settable = sorted(cls._settable or ())
        return InvalidSceneError(
            f"{cls.__name__}: {name!r} is not a parameter of {cls.__name__} (settable: {settable}); "
            f"use {cls.__mro__[1].__name__}({name}=...) for a material with that parameter"
        )

    def _set_param(self, param: Param, value: Any) -> None:
        if param.name in type(self)._fixed_params:
            raise type(self)._not_settable(param.name)
        if param.fixed:
            raise InvalidSceneError(
                f"{param.name}: fixed at creation (got {value!r}); create a new {type(self).__name__} instead"
            )
        checked = param.check(value, self)
        self._values[param.name] = checked
        self._param_changed(param)

    def _param_changed(self, param: Param) -> None:
        """Called after an assignment changed a parameter (subclasses bump their revision)."""

    @classmethod
    def parameter_names(cls) -> tuple[str, ...]:
        return tuple(p.name for p in cls._stored)

    def parameters(self) -> dict[str, Any]:
        """A copy of every stored parameter by name (code in blendify_core reads attributes instead)."""
        return dict(self._values)

    def __copy__(self) -> Any:
        # parameters live in one dict: a shallow copy must not share it, or setting an attribute on the
        # copy would change the original
        new = type(self).__new__(type(self))
        new.__dict__.update(self.__dict__)
        new.__dict__["_values"] = dict(self._values)
        return new


strict_api(Declared)


# ---------------------------------------------------------------------------------------------------
# the scene-file schema
# ---------------------------------------------------------------------------------------------------


def encode_value(p: Param, value: Any, arrays: dict[str, AnyArray], prefix: str, obj: Any = None) -> Any:
    """A stored value as JSON (texture maps add their images to ``arrays`` under ``prefix``)."""
    if p.encode_fn is not None:
        return p.encode_fn(obj, value)
    if p.kind in ("texture", "normal_map"):
        return None if value is None else value.to_dict(arrays, f"{prefix}{p.name}.")
    if isinstance(value, tuple):
        return list(value)
    return value


def encode_params(obj: Declared, arrays: dict[str, AnyArray], prefix: str = "") -> dict[str, Any]:
    """``{name: JSON value}`` for every stored parameter of ``obj``, in declaration order."""
    values = obj._values
    return {p.name: encode_value(p, values[p.name], arrays, prefix, obj) for p in type(obj)._stored}


def _resolve(path: str, base_dir: str | None) -> str:
    if base_dir is not None and not os.path.isabs(path):
        return os.path.join(base_dir, path)
    return path


def decode_value(p: Param, value: Any, arrays: Mapping[str, AnyArray], base_dir: str | None = None) -> Any:
    """The constructor input a JSON value stands for (validation happens in the constructor)."""
    if p.kind in ("texture", "normal_map") and value is not None:
        src = arrays[value["image"]] if value.get("image") else _resolve(value["path"], base_dir)
        if value["kind"] == "normal_map":
            return NormalMap(src, strength=value["strength"])
        return TextureMap(src, channel=value["channel"])
    return value


def decode_params(
    where: str,
    params: Iterable[Param],
    d: Mapping[str, Any],
    arrays: Mapping[str, AnyArray],
    base_dir: str | None = None,
) -> dict[str, Any]:
    """Constructor keywords from a scene file's ``params`` (missing keys take the declared default;
    unknown keys raise InvalidSceneError naming them)."""
    by_name = {p.name: p for p in params}
    unknown = sorted(set(d) - set(by_name))
    if unknown:
        raise InvalidSceneError(f"{where}: unknown parameter(s) {unknown}")
    return {k: decode_value(by_name[k], v, arrays, base_dir) for k, v in d.items()}
