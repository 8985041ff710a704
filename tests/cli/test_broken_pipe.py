"""A reader of stdout that goes away (``microconveyor ... | head -1``) ends the command quietly:
no traceback, no error line, exit status 141 (128 + SIGPIPE, as a shell reports a writer killed
by SIGPIPE), in the one entry point every command goes through."""
import subprocess
import sys
import textwrap

import pytest

from microconveyor_env.cli.base import EXIT_BROKEN_PIPE

# a command that prints far more than a pipe holds, registered beside the real ones
CHATTY = textwrap.dedent("""
    import sys
    from microconveyor_env.cli import command, main

    @command("chatty", "many lines")
    def chatty(args):
        for i in range(200_000):
            print(f"line {i}")

    sys.exit(main(sys.argv[1:]))
""")


def test_piping_into_head_ends_quietly():
    r = subprocess.run(f'"{sys.executable}" -c "$CHATTY" chatty | head -1; '
                       'echo "status ${PIPESTATUS[0]}" >&2',
                       shell=True, executable="/bin/bash", capture_output=True, text=True,
                       env={"CHATTY": CHATTY, "PATH": "/usr/bin:/bin"}, timeout=300)
    assert r.stdout == "line 0\n"
    assert r.stderr == f"status {EXIT_BROKEN_PIPE}\n", r.stderr


@pytest.mark.parametrize("argv, status", [
    (["contact", "--json"], EXIT_BROKEN_PIPE), (["contact"], EXIT_BROKEN_PIPE),
    (["sweep", "--freq", "200:800:300", "--no-progress", "--json"], EXIT_BROKEN_PIPE),
    (["--help"], 0),  # argparse's help drops a failed write itself and exits 0
])
def test_a_reader_gone_before_the_output_ends_every_command_quietly(argv, status):
    """The reader closes the pipe before the command writes: the write fails at once."""
    p = subprocess.Popen([sys.executable, "-m", "microconveyor_env.cli", *argv],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    p.stdout.close()
    err = p.stderr.read()
    assert p.wait(timeout=300) == status
    assert err == "", err


def test_a_broken_pipe_of_another_file_is_an_error_line(capsys, monkeypatch):
    """Only stdout's reader going away is quiet: a broken pipe elsewhere is reported."""
    from microconveyor_env.cli import base, command, main

    # the command is registered in a copy of the registry: later tests in this process see none
    monkeypatch.setattr(base, "COMMANDS", dict(base.COMMANDS))

    @command("broken-elsewhere", "a pipe of its own breaks")
    def broken(args):
        raise BrokenPipeError(32, "Broken pipe")

    assert main(["broken-elsewhere"]) == 2
    assert "BrokenPipeError" in capsys.readouterr().err
