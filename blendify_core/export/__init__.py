"""Scene exporters that need no engine: glTF 2.0 (``.glb`` / ``.gltf``) and the offline HTML viewer.

Reached from the IR through the registry (:func:`blendify_core.registry.exporter_for_format`):
``scene.export("x.glb")`` and ``scene.show()``. Formats an engine writes (``.blend``, Mitsuba XML) live in
their backend and are found with :func:`blendify_core.registry.backend_for_format`.
"""

from __future__ import annotations

from blendify_core.export.gltf import export_gltf, gltf_document

__all__ = ["export_gltf", "gltf_document"]
