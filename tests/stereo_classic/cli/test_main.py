from stereo_classic.cli import main


def test_help_exits_zero(capsys):
    assert main(["--help"]) == 0
    assert "usage" in capsys.readouterr().out.lower()


def test_unknown_command_is_usage_error():
    assert main(["no-such-command"]) == 2


def test_every_subcommand_is_registered(capsys):
    assert main(["--help"]) == 0
    out = capsys.readouterr().out
    for command in ("run", "disparity", "calibrate"):
        assert command in out


def test_no_command_prints_help_and_is_usage_error(capsys):
    assert main([]) == 2
    assert "usage" in capsys.readouterr().err.lower()


def test_verbosity_flags_are_accepted_after_the_command():
    from stereo_classic.cli import build_parser

    parser = build_parser()
    args = parser.parse_args(["run", "-q"])
    assert args.quiet is True and args.verbose == 0
    args = parser.parse_args(["-q", "disparity", "l.png", "r.png", "-o", "o.pfm"])
    assert args.quiet is True
    args = parser.parse_args(["calibrate", "-vv", "--folder", "d", "--board-size", "9x6", "--square", "0.025", "-o", "r.yaml"])
    assert args.verbose == 2 and args.quiet is False
