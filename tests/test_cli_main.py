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
