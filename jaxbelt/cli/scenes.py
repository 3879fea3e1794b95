"""``jaxbelt scenes``: list the built-in scenes."""

from ..scene import builtin_scene_names, load_scene


def add_parser(subparsers):
    p = subparsers.add_parser("scenes", help="list the built-in scenes")
    p.set_defaults(func=run)
    return p


def run(args):
    for name in builtin_scene_names():
        sc = load_scene(name)
        print(f"{name:32s} {sc.kind}  {sc.description}")
    return 0
