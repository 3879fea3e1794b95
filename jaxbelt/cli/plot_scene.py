"""``jaxbelt plot-scene``: draw rollers, belt path, contact and tracer points."""

from ..mesh import build_mesh
from ..plot import plot_scene
from ._common import SCENE_HELP, output_file, scene_from_args


def add_parser(subparsers):
    p = subparsers.add_parser("plot-scene", help="draw rollers, belt path, contact and tracer points")
    p.add_argument("scene", help=SCENE_HELP)
    p.add_argument("--out", default=None, help="PNG path (default SCENE-scene.png)")
    p.set_defaults(func=run)
    return p


def run(args):
    out = output_file("--out", args.out)  # checked before the scene is loaded
    scene = scene_from_args(args.scene)
    out = out or output_file("--out", f"{scene.name}-scene.png")
    plot_scene(scene, build_mesh(scene), out)
    print(f"wrote {out}")
    return 0
