"""The IR: what a scene is, exactly. Plain numpy objects, validated on entry, read-only arrays.

Cameras, lights, materials, colour sources, renderables, transforms and geometry, the validation
policy, and the :class:`~blendify_core.ir.scene.Scene` that holds them. Nothing here knows a backend or
renders anything; the render pipeline (:mod:`blendify_core.pipeline`) and the backends read the IR.
"""
