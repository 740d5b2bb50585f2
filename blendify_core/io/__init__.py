"""Files in and out, below the IR: atomic writes with the user's file mode, the scene-file container.

Nothing here imports the IR: the IR turns itself into a header and arrays (:mod:`blendify_core.ir.serialize`)
and these modules store them.
"""
