"""The headless browser's command line: WebGL without multisampling unless asked for."""

from __future__ import annotations

from pathlib import Path

from loosefit.view.headless import FLAGS, NO_ANTIALIAS, command


def test_the_command_line_drops_multisampling_by_default():
    argv = command("chromium", Path("/tmp/profile"), 640, 400)
    assert argv[0] == "chromium" and argv[-1] == "about:blank"
    assert "--webgl-antialiasing-mode=none" in argv and set(NO_ANTIALIAS) <= set(argv)
    assert "--window-size=640,400" in argv and "--user-data-dir=/tmp/profile" in argv
    assert argv[1 : 1 + len(FLAGS)] == list(FLAGS)


def test_antialias_and_extra_flags():
    argv = command("chromium", Path("/p"), 1280, 800, antialias=True, flags=["--x=1", "--y"])
    assert not set(NO_ANTIALIAS) & set(argv)
    # after the defaults, so that one given again wins (Chromium keeps the last)
    assert argv.index("--x=1") > argv.index(FLAGS[-1]) and argv.index("--y") > argv.index("--x=1")
