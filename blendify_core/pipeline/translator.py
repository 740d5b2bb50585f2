"""One translator shape for every backend: one handler per IR type, capabilities declared beside it.

A backend's translator subclasses :class:`Translator` and marks one method per IR type with
:func:`handles`::

    class MitsubaTranslator(Translator):
        backend = "mitsuba"

        @handles(SphereNURBS, features={"primitive.sphere": EXACT})
        def sphere(self, sphere, ctx): ...

        @handles(AreaLight, features={"light.area": EXACT, "light.area.disk": EXACT})
        def area_light(self, light, ctx): ...

:meth:`Translator.dispatch` calls the handler registered for the object's *exact* type, so a subclass that
nobody registered (a user's ``class MyMesh(Mesh)``) is refused by name instead of being translated as
its parent. Every IR type in :data:`blendify_core.ir.types.IR_TYPES` gets a handler in every backend,
even one that only records why it is ignored (:meth:`TranslationContext.ignore`); the base answers every
type without a handler in one place, with :class:`~blendify_core.errors.UnsupportedFeatureError` naming the
type and the backend. :func:`check_handlers` runs that check on a whole scene before a backend sees it.

Capabilities (:mod:`blendify_core.pipeline.capabilities`) are declared with the handler that implements
them (``features=``); :meth:`Translator.capabilities` gathers them, and a feature no handler declares is
"unsupported" (the one default).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar, TypeVar

from blendify_core.errors import UnsupportedFeatureError
from blendify_core.ir.types import IR_TYPES, iter_ir_objects
from blendify_core.pipeline.capabilities import ALL_FEATURES, Capability

__all__ = [
    "EXACT",
    "Translator",
    "TranslationContext",
    "approximate",
    "check_handlers",
    "exact",
    "handles",
    "unsupported",
]

#: the capability of a feature a handler renders exactly
EXACT = Capability("exact")


def exact(note: str) -> Capability:
    """The capability of a feature a handler renders exactly, with a note saying how (formulas, engine names)."""
    return Capability("exact", note)


def approximate(note: str) -> Capability:
    """The capability of a feature a handler approximates (``note`` says how; listed in meta)."""
    return Capability("approximate", note)


def unsupported(note: str) -> Capability:
    """The capability of a feature a handler refuses (``note`` says why)."""
    return Capability("unsupported", note)


_F = TypeVar("_F", bound=Callable[..., Any])


@dataclass(frozen=True)
class _HandlerSpec:
    types: tuple[type, ...]
    features: Mapping[str, Capability]


def handles(*types: type, features: Mapping[str, Capability] | None = None) -> Callable[[_F], _F]:
    """Mark a translator method as the handler of ``types`` (exact types) and declare the capabilities of
    the ``features`` it implements."""
    if not types or not all(isinstance(t, type) for t in types):
        raise TypeError(f"handles: expected IR classes, got {types!r}")
    unknown = sorted(set(features or {}) - set(ALL_FEATURES))
    if unknown:
        raise TypeError(f"handles: unknown feature name(s) {unknown}; see blendify_core.pipeline.capabilities")

    def mark(fn: _F) -> _F:
        fn._blendify_handles = _HandlerSpec(tuple(types), dict(features or {}))  # type: ignore[attr-defined]
        return fn

    return mark


@dataclass
class TranslationContext:
    """What one translation collects besides the native scene: approximations made and objects ignored."""

    approximations: list[str] = field(default_factory=list)
    ignored: list[str] = field(default_factory=list)

    def approximate(self, text: str) -> None:
        """Record an approximation made for this scene (listed in ``result.meta["approximations"]``)."""
        if text not in self.approximations:
            self.approximations.append(text)

    def ignore(self, obj: object, why: str) -> None:
        """Record that ``obj`` contributes nothing in this backend, and why."""
        self.ignored.append(f"{type(obj).__name__}: {why}")


class Translator:
    """Base of every backend translator. Subclasses set :attr:`backend` and mark handlers with :func:`handles`;
    handler tables and capability declarations are inherited and may be overridden per type."""

    #: the backend name used in error messages
    backend: ClassVar[str] = "base"
    #: exact IR type -> name of the handler method
    _handlers: ClassVar[dict[type, str]] = {}
    #: feature -> capability, as declared by the handlers (and :attr:`extra_capabilities`)
    _declared: ClassVar[dict[str, Capability]] = {}
    #: capabilities not tied to an IR type (outputs, for example), declared by the subclass
    extra_capabilities: ClassVar[Mapping[str, Capability]] = {}

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        handlers: dict[type, str] = {}
        declared: dict[str, Capability] = {}
        for base in reversed(cls.__mro__[1:]):
            handlers.update(getattr(base, "_handlers", {}))
            declared.update(getattr(base, "_declared", {}))
        for name, member in cls.__dict__.items():
            spec = getattr(member, "_blendify_handles", None)
            if isinstance(spec, _HandlerSpec):
                for t in spec.types:
                    handlers[t] = name
                declared.update(spec.features)
        declared.update(cls.__dict__.get("extra_capabilities", {}))
        cls._handlers = handlers
        cls._declared = declared

    # -- dispatch --------------------------------------------------------------------------------------
    @classmethod
    def handler_name(cls, obj_type: type) -> str | None:
        """The name of the handler of exactly ``obj_type``, or None."""
        return cls._handlers.get(obj_type)

    @classmethod
    def refuse(cls, obj: object, where: str | None = None) -> UnsupportedFeatureError:
        """The error for an object whose exact type has no handler in this backend."""
        t = type(obj)
        name = f"{t.__module__}.{t.__qualname__}"
        at = f" (used by {where})" if where else ""
        hint = ""
        parents = [b.__name__ for b in t.__mro__[1:] if b in cls._handlers]
        if parents:
            hint = (
                f"; it is a subclass of {parents[0]}, which is handled, but subclasses are not translated as "
                f"their parent: use {parents[0]} itself"
            )
        return UnsupportedFeatureError(
            f"backend {cls.backend!r} has no handler for the IR type {name}{at}{hint}",
            feature=f"type.{t.__qualname__}",
            backend=cls.backend,
        )

    def dispatch(self, obj: object, *args: Any, **kwargs: Any) -> Any:
        """Call the handler registered for ``type(obj)`` (exactly); raise UnsupportedFeatureError without one."""
        name = self._handlers.get(type(obj))
        if name is None:
            raise self.refuse(obj)
        return getattr(self, name)(obj, *args, **kwargs)

    # -- declarations ----------------------------------------------------------------------------------
    @classmethod
    def capabilities(cls) -> dict[str, Capability]:
        """Every feature of :data:`~blendify_core.pipeline.capabilities.ALL_FEATURES`: as declared by the
        handlers, "unsupported" (not declared) otherwise."""
        return {
            f: cls._declared.get(f, Capability("unsupported", f"not declared by the {cls.backend} translator"))
            for f in ALL_FEATURES
        }

    @classmethod
    def declared(cls) -> dict[str, Capability]:
        """Only what the handlers (and :attr:`extra_capabilities`) declare, without the default."""
        return dict(cls._declared)

    @classmethod
    def missing_handlers(cls, types: Iterable[type] = IR_TYPES) -> list[type]:
        """IR types without a handler (every backend must have none missing)."""
        return [t for t in types if t not in cls._handlers]


def check_handlers(translator: type[Translator], scene: object) -> None:
    """Refuse, by name, the first IR object of ``scene`` whose exact type has no handler in ``translator``."""
    for obj, where in iter_ir_objects(scene):
        if translator.handler_name(type(obj)) is None:
            raise translator.refuse(obj, where)
