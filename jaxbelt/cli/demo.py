"""``jaxbelt demo``: ``jaxbelt simulate`` on the built-in default scene, writing .npz and .png."""

from . import simulate

DEFAULT_SCENE = "two-roller-1d"


def add_parser(subparsers):
    d = subparsers.add_parser("demo", help=f"simulate the built-in default scene ({DEFAULT_SCENE}), write .npz and .png")
    d.add_argument("--out", default=None)
    d.add_argument("--plot", default=None)
    d.add_argument("--json", action="store_true")
    d.set_defaults(func=run)
    return d


def run(args):
    args.scene = DEFAULT_SCENE
    args.t_end = args.dt = args.integrator = None
    args.out = args.out or "jaxbelt-demo.npz"
    args.plot = args.plot or "jaxbelt-demo.png"
    return simulate.run(args, demo=True)
