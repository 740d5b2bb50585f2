"""Leave in standard formats and look before rendering: glTF 2.0 (.glb / .gltf), a Mitsuba 3 scene (.xml)
and the offline HTML view of the scene; the .glb read back with add_trimesh keeps the objects' tags."""

from __future__ import annotations

import warnings

from _common import out_dir, parser

import blendify_core as bf
from blendify_core.testing import every_feature_scene


def main() -> None:
    args = parser(__doc__, size=320, samples=16).parse_args()
    out = out_dir(args)
    scene = every_feature_scene(resolution=(args.size, args.size * 3 // 4))
    with warnings.catch_warnings(record=True) as notes:  # what glTF cannot express, said once per file
        warnings.simplefilter("always")
        scene.export(out / "scene.glb")
        scene.export(out / "scene.gltf")  # + scene.bin
    for note in {str(n.message) for n in notes}:
        print(note)
    try:
        scene.export_mitsuba(out / "scene.xml", samples=args.samples, transparent_background=False)
        print(f"Mitsuba scene: {out / 'scene.xml'} (meshes and bitmaps in {out / 'scene_files'})")
    except bf.BlendifyError as exc:
        print(f"no Mitsuba XML: {exc}")
    view = scene.show(viewer="html", path=out / "view.html", open_browser=False)
    print(f"offline viewer page: {view.path} (open it in a web browser)")
    back = bf.Scene()
    back.renderables.add_trimesh(out / "scene.glb", merge=False)  # back in +Z up, with the tags
    print(f"read back from the .glb: {sorted(back.renderables.keys())}")


if __name__ == "__main__":
    main()
