from stereo_classic.cli import main


def test_help_exits_zero(capsys):
    assert main(["--help"]) == 0
    assert "usage" in capsys.readouterr().out.lower()


def test_unknown_command_is_usage_error():
    assert main(["no-such-command"]) == 2
