"""Which registered backends the batch's worker processes can import, checked before any work starts.

Local pool workers and Ray workers are fresh interpreters that never run the parent's ``__main__``: a
backend class defined there (or inside a function) cannot reach them, and a ``"module:Class"`` path that
names the running script would run that script again in every worker.
"""

from __future__ import annotations

import os
import re
import sys
from types import ModuleType

from blendify_core import registry as backend_mod
from blendify_core.batch.jobs import RenderJob
from blendify_core.errors import InvalidSceneError

__all__ = ["check_backends_importable"]


def _main_description(main: ModuleType | None) -> str:
    path = getattr(main, "__file__", None)
    if isinstance(path, str) and not path.startswith("<"):
        return f"the script {os.path.basename(path)}"
    return "code run from stdin, `python -c` or a notebook"


def _names_main(module: str, main: ModuleType) -> bool:
    """True when ``module`` is the script running as ``__main__`` (importing it would run it again)."""
    spec = getattr(main, "__spec__", None)
    if spec is not None and getattr(spec, "name", None) == module:
        return True
    path = getattr(main, "__file__", None)
    if not isinstance(path, str) or path.startswith("<") or not os.path.isfile(path):
        return False
    mod = sys.modules.get(module)
    if mod is not None:
        origin = getattr(mod, "__file__", None)
    elif "." in module:  # finding a submodule would import its packages: leave those to the worker
        return False
    else:
        import importlib.util

        try:
            found = importlib.util.find_spec(module)
        except (ImportError, ValueError):
            return False
        origin = None if found is None else found.origin
    try:
        return isinstance(origin, str) and os.path.samefile(origin, path)
    except OSError:
        return False


def check_backends_importable(jobs: list[RenderJob]) -> None:
    """Fail before any work when a job's backend is registered in a way worker processes cannot import:
    a class defined in ``__main__`` or inside a function, or a "module:Class" path naming the script
    being run (workers are fresh interpreters that never run ``__main__``)."""
    main = sys.modules.get("__main__")
    for i, job in enumerate(jobs):
        if job.backend is None:
            continue
        target = backend_mod._registered.get(job.backend)
        name = job.backend
        if isinstance(target, type):
            qual = target.__qualname__
            if target.__module__ == "__main__":
                where = f"defined in __main__ ({_main_description(main)})"
                why = "never run __main__"
            elif "<locals>" in qual:
                where = f"defined inside a function ({target.__module__}.{qual})"
                why = "import a backend class by module and name"
            else:
                continue
            cls = qual.rsplit(".", 1)[-1]
            module = re.sub(r"\W", "_", name) + "_backend"
            raise InvalidSceneError(
                f"jobs[{i}]: backend {name!r} is registered as the class {cls} {where}; render_many's worker "
                f"processes are fresh Python interpreters that {why}, so they cannot import it. Move {cls} "
                f"to the top level of a module (e.g. {module}.py next to your script) and register it by path: "
                f"bf.register_backend({name!r}, '{module}:{cls}'), or render in this process with "
                "executor=concurrent.futures.ThreadPoolExecutor(1)"
            )
        if isinstance(target, str) and main is not None:
            module, _, cls = target.partition(":")
            if _names_main(module, main):
                raise InvalidSceneError(
                    f"jobs[{i}]: backend {name!r} is registered as {target!r}, but {module!r} is "
                    f"{_main_description(main)} being run: every worker would import it and run the "
                    f"script again. Move {cls or 'the backend class'} into a module of its own and register "
                    "that path"
                )
