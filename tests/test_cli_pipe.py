"""Output into a pipe whose reader has gone (``fluidem examples | head``) ends quietly, like standard tools."""

import subprocess
import sys

import pytest

from fluidem.cli import BROKEN_PIPE_STATUS


@pytest.mark.parametrize("command", [["examples"], ["reference"]])
def test_a_closed_pipe_gives_no_error_message(command):
    p = subprocess.Popen([sys.executable, "-m", "fluidem", *command], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    p.stdout.close()  # the reader exits before fluidem writes
    err = p.stderr.read().decode()
    p.stderr.close()
    assert p.wait() == BROKEN_PIPE_STATUS == 141
    assert err == ""  # before: "fluidem: error: Broken pipe", status 2
