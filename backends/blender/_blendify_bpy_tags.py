"""Make the installed ``bpy`` wheel's tags agree with its file name, so ``uv`` stops reinstalling it.

The bpy 5.0.1 Linux wheel is named ``bpy-5.0.1-cp311-cp311-manylinux_2_28_x86_64.whl`` but its
``bpy-5.0.1.dist-info/WHEEL`` file says ``Tag: cp39-cp39-manylinux_2_28_x86_64``. uv (at least since
0.8.15) checks the tags of installed distributions on every ``uv sync`` / ``uv run``, finds a CPython 3.9
package in a 3.11 environment and uninstalls and reinstalls bpy, every time. A ``uv run`` started while another
process renders deletes bpy's files under that render (``No module named '_bpy_types'``, ``libtbb.so.12``
missing, the Cycles add-on not registered).

The blendify-blender distribution installs this module at the top level of site-packages together with
``_blendify_bpy_tags.pth``, whose single line calls :func:`fix` when the interpreter starts. The first
Python started in the environment after bpy was (re)installed rewrites that one line to the running
interpreter's tag (``cp311-cp311-manylinux_2_28_x86_64``, the tag of the wheel's file name) and the
WHEEL entry of ``RECORD``; from then on uv finds the tags consistent and installs nothing.
``blendify_blender`` calls :func:`fix` again when it is imported (for an interpreter started with ``-S``).

Start-up cost: when the tag is already right the check is one small file read (~16 us measured);
importing this module, which imports only ``os`` and ``sys``, brings the total to ~0.3 ms. It never
raises and prints nothing: a read-only site-packages, a missing bpy or any other surprise leaves
everything as it was. It touches nothing but the known-bad tag of the bpy version that blendify-blender
pins (:data:`BPY_VERSION`), and only on CPython 3.11. The rewrite is atomic (a temporary file moved over
WHEEL with ``os.replace``): uv hard-links installed files to its cache, so writing into the existing file
would change uv's cached copy too.
"""

import os
import sys

__all__ = ["BPY_VERSION", "BAD_TAG", "fix", "fix_dist_info"]

#: the bpy version blendify-blender pins (``bpy==...`` in backends/blender/pyproject.toml; a test checks)
BPY_VERSION = "5.0.1"
#: the wrong tag that wheel's WHEEL file carries
BAD_TAG = "cp39-cp39-manylinux_2_28_x86_64"
_PLATFORM = "manylinux_2_28_x86_64"


def _interpreter_ok() -> bool:
    return sys.implementation.name == "cpython" and sys.version_info[:2] == (3, 11)


def fix(site_dirs: list[str] | None = None) -> bool:
    """Fix bpy's WHEEL tag in the first of ``site_dirs`` that holds bpy's dist-info (default: this
    module's own directory, then every ``site-packages`` entry of ``sys.path``).

    Returns True when it rewrote the file, False otherwise (nothing to do, not this interpreter, bpy not
    installed, or the file could not be written). Never raises."""
    try:
        if not _interpreter_ok():
            return False
        if site_dirs is None:
            site_dirs = [os.path.dirname(os.path.abspath(__file__))]
            site_dirs += [p for p in sys.path if p.endswith("site-packages") and p not in site_dirs]
        name = f"bpy-{BPY_VERSION}.dist-info"
        for d in site_dirs:
            dist_info = os.path.join(d, name)
            if os.path.isfile(os.path.join(dist_info, "WHEEL")):
                return fix_dist_info(dist_info)
    except Exception:
        pass
    return False


def fix_dist_info(dist_info: str) -> bool:
    """Rewrite the ``Tag:`` line of ``dist_info/WHEEL`` when it is :data:`BAD_TAG` (CPython 3.11 only).

    Returns True when the file was rewritten. Never raises."""
    try:
        if not _interpreter_ok():
            return False
        wheel = os.path.join(dist_info, "WHEEL")
        with open(wheel, "rb") as f:
            data = f.read()
        bad = b"Tag: " + BAD_TAG.encode()
        lines = data.splitlines(keepends=True)
        if not any(line.rstrip(b"\r\n") == bad for line in lines):
            return False
        py = f"cp{sys.version_info[0]}{sys.version_info[1]}"
        good = f"Tag: {py}-{py}-{_PLATFORM}".encode()
        new = b"".join(good + line[len(bad) :] if line.rstrip(b"\r\n") == bad else line for line in lines)
        if not _replace(wheel, new):
            return False
    except Exception:
        return False
    try:
        _update_record(dist_info, new)
    except Exception:
        pass
    return True


def _replace(path: str, data: bytes) -> bool:
    """Write ``data`` to a temporary file beside ``path`` and move it over ``path`` (same mode)."""
    tmp = f"{path}.{os.getpid()}.tmp"
    try:
        mode = os.stat(path).st_mode & 0o777
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, mode)
        try:
            os.write(fd, data)
        finally:
            os.close(fd)
        os.replace(tmp, path)
        return True
    except Exception:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        return False


def _update_record(dist_info: str, wheel_data: bytes) -> None:
    """Give the WHEEL row of RECORD the new file's hash and size (only reached once per install)."""
    import base64
    import hashlib

    record = os.path.join(dist_info, "RECORD")
    with open(record, "rb") as f:
        lines = f.read().splitlines(keepends=True)
    key = os.path.basename(dist_info).encode() + b"/WHEEL,"
    digest = base64.urlsafe_b64encode(hashlib.sha256(wheel_data).digest()).rstrip(b"=")
    row = key + b"sha256=" + digest + b"," + str(len(wheel_data)).encode()
    out = [row + line[len(line.rstrip(b"\r\n")) :] if line.startswith(key) else line for line in lines]
    if out != lines:
        _replace(record, b"".join(out))
