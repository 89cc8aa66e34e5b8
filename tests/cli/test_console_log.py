"""gyrodenoise.console.log: the one way a command tells a person what it does (stderr, one
line, nothing on stdout, nothing when quiet)."""
from gyrodenoise.console import log


def test_log_writes_one_line_on_stderr_with_its_prefix(capfd):
    log("fitting 3 terms", prefix="gyrodenoise gap: ")
    log("not shown", quiet=True)
    out, err = capfd.readouterr()
    assert out == "" and err == "gyrodenoise gap: fitting 3 terms\n"
