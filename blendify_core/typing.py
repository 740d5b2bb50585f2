"""Array types shared by the core's annotations (numpy only).

``Float32Array`` etc. are ``numpy.typing.NDArray`` of one dtype; ``AnyArray`` is an array whose dtype the
code does not fix (it keeps the caller's). Use them in annotations; at run time they are plain aliases.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "Float32Array",
    "Float64Array",
    "FloatArray",
    "Int32Array",
    "IntArray",
    "BoolArray",
    "UInt8Array",
    "AnyArray",
]

#: float32 array (render outputs: rgba, depth, normal, albedo)
Float32Array = NDArray[np.float32]
#: float64 array (IR geometry, poses, camera maths)
Float64Array = NDArray[np.float64]
#: array of any floating dtype
FloatArray = NDArray[np.floating[Any]]
#: int32 array (the instance output)
Int32Array = NDArray[np.int32]
#: array of any integer dtype (indices, faces)
IntArray = NDArray[np.integer[Any]]
#: boolean array (masks)
BoolArray = NDArray[np.bool_]
#: uint8 array (8-bit images)
UInt8Array = NDArray[np.uint8]
#: array whose dtype the code keeps as given
AnyArray = NDArray[Any]
