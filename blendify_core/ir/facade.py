"""The ``add_*`` / ``set_*`` methods of the scene's collections, derived from the classes they build.

A facade's signature is its class's constructor signature (its named parameters, in order), then the pose
(``rotation_mode``, ``rotation``, ``translation``) and ``tag``, then any ``trailing`` parameters (lights:
``color_space``): no parameter list is written twice. Calls are checked against that signature, so unknown,
surplus or missing arguments raise InvalidSceneError naming them (never a bare TypeError).
"""

from __future__ import annotations

import inspect
from collections.abc import Callable, Sequence
from typing import Any, TypeVar

from blendify_core.errors import InvalidSceneError
from blendify_core.ir.params import POSE, TAG, Param

__all__ = ["facade", "FacadeAction"]

T = TypeVar("T")
#: what a facade does with the new object: ``action(collection, cls, arguments) -> returned object``
FacadeAction = Callable[[Any, type, dict[str, Any]], Any]

_POK = inspect.Parameter.POSITIONAL_OR_KEYWORD


def _parameter(p: Param) -> inspect.Parameter:
    return inspect.Parameter(p.name, _POK, default=p.default, annotation=p.signature_annotation)


def facade(
    cls: type[T],
    name: str,
    owner: str,
    action: FacadeAction,
    *,
    pose: bool = True,
    trailing: Sequence[Param] = (),
    doc: str = "",
) -> Callable[..., T]:
    """A method ``owner.name`` that builds ``cls`` from its arguments and hands it to ``action``."""
    extra = tuple(POSE) + (TAG,) if pose else ()
    skip = {p.name for p in extra} | {p.name for p in trailing}
    own = [p.replace() for p in inspect.signature(cls).parameters.values() if p.kind is _POK and p.name not in skip]
    params = [inspect.Parameter("self", _POK), *own, *(_parameter(p) for p in extra + tuple(trailing))]
    sig = inspect.Signature(params, return_annotation=cls.__name__)
    qualname = f"{owner}.{name}"

    def method(self: Any, *args: Any, **kwargs: Any) -> T:
        try:
            bound = sig.bind(self, *args, **kwargs)
        except TypeError as exc:
            raise InvalidSceneError(f"{qualname}: {exc}") from None
        bound.apply_defaults()
        arguments = dict(bound.arguments)
        del arguments["self"]
        return action(self, cls, arguments)  # type: ignore[no-any-return]

    method.__name__ = name
    method.__qualname__ = qualname
    method.__doc__ = doc or f"Add a :class:`{cls.__name__}` (its parameters: docs/parameters.md) and return it."
    method.__signature__ = sig  # type: ignore[attr-defined]
    return method
