"""The same scene through all three backends, compared pairwise: colour, depth, mask, normals."""

from __future__ import annotations

from _common import out_dir, parser

import blendify_core as bf
from blendify_core.testing import primitives_scene


def main() -> None:
    args = parser(__doc__, size=160, samples=64).parse_args()
    out = out_dir(args)
    scene = primitives_scene(resolution=(args.size, args.size * 3 // 4))
    report = bf.crosscheck(scene, samples=args.samples, outputs=("rgb", "depth", "normal", "instance"))
    for name, reason in report.skipped.items():
        print(f"skipped {name}: {reason}")
    for (a, b), cmp in report.pairs.items():
        m = cmp.metrics
        print(
            f"{a} vs {b}: colour mean rel. error {m['rgb']['mean_rel_error']:.3f}, "
            f"depth q99 {m['depth']['rel_diff_q99']:.1e}, mask IoU {m['mask']['iou']:.4f} -> "
            f"{'pass' if cmp.passed else 'differs'} ({cmp.tier})"
        )
    report.save(out / "three_backends")
    print(f"contact sheet and report in {out}/three_backends/")


if __name__ == "__main__":
    main()
