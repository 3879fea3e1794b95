"""``jaxbelt scenes`` (:mod:`jaxbelt.cli.scenes`): one line per TOML file of the package's scene
folder, in name order, each the name in a 32-character column, the model kind and the scene's
description; against the folder's files and hand-copied lines of two scenes."""

import argparse
from pathlib import Path

import jaxbelt
from jaxbelt.cli import scenes

SCENE_FILES = sorted(p.stem for p in (Path(jaxbelt.__file__).parent / "scenes").glob("*.toml"))


def test_one_line_per_scene_file_in_name_order(capsys):
    assert scenes.run(argparse.Namespace()) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(SCENE_FILES) >= 40 and len(lines) == len(SCENE_FILES)
    assert [line[:32].rstrip() for line in lines] == SCENE_FILES
    assert all(line[32] == " " and line[33:35] in ("1d", "2d") and line[35:37] == "  " for line in lines)


def test_lines_of_two_scenes(capsys):
    scenes.run(argparse.Namespace())
    lines = {line[:32].rstrip(): line for line in capsys.readouterr().out.splitlines()}
    assert lines["two-roller-1d"] == ("two-roller-1d" + " " * 19 + " 1d  Two equal rollers (drive + idle), the "
                                      "source's 1D setup (§6)")
    assert lines["three-roller-steered"] == ("three-roller-steered" + " " * 12 + " 2d  Three-roller machine with a PI "
                                             "steering loop on roller 2 (edge sensor, ±3 mrad): the design scene")


def test_the_subcommand_is_registered_with_its_handler():
    parser = argparse.ArgumentParser()
    sub = parser.add_subparsers()
    p = scenes.add_parser(sub)
    assert p.prog.endswith(" scenes")
    args = parser.parse_args(["scenes"])
    assert args.func is scenes.run
