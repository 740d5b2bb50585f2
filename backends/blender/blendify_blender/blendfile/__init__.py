""".blend files on the Cycles backend: attach (parse a .blend into the IR) and attached blends (their raw
content rendered by Cycles). Export (write an IR scene as a .blend) builds the scene with the translator,
which uses this package, so it lives above both: :mod:`blendify_blender.export`.

Security: nothing embedded in a file is ever executed, whatever the user's Blender preferences say
(:mod:`.safety`).

Modules, bottom to top:

- :mod:`.safety`: the auto-run guard, path checks, the safe append of a file's scenes;
- :mod:`.common`: notes, the ``blendify_tag`` property, matrix and colour conversions;
- :mod:`.images`: images -> texture files or pixels (packed images unpacked to a cache folder);
- :mod:`.nodes`: material node trees -> IR materials and colour-source descriptions;
- :mod:`.geometry`: meshes and point clouds; :mod:`.lights`: lights and the world; :mod:`.camera`;
- :mod:`.attach`: :func:`attach_blend` and :func:`append_blend_scenes` (used by the translator to render
  ``scene.attachments``);

Layering: blendfile -> translate -> export (:mod:`blendify_blender.export`: ``export_blend``, through
``Scene.export_blend``).
"""

from __future__ import annotations

from blendify_blender.blendfile.attach import AttachedBlend, BlendAttachWarning, append_blend_scenes, attach_blend
from blendify_blender.blendfile.camera import blender_camera_intrinsics
from blendify_blender.blendfile.common import TAG_PROPERTY
from blendify_blender.blendfile.images import default_texture_cache_dir
from blendify_blender.blendfile.safety import check_blend_path, scripts_auto_execute_disabled

__all__ = [
    "TAG_PROPERTY",
    "AttachedBlend",
    "BlendAttachWarning",
    "append_blend_scenes",
    "attach_blend",
    "blender_camera_intrinsics",
    "check_blend_path",
    "default_texture_cache_dir",
    "scripts_auto_execute_disabled",
]
