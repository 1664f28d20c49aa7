"""A test's guard that msid works in process: every way Python starts a process fails the test."""
import os
import subprocess


def refuse_processes(monkeypatch):
    """Make every way of starting a process fail the test (subprocess, os spawn/fork/exec)."""
    def refuse(*a, **k):
        raise AssertionError("a process was started")
    monkeypatch.setattr(subprocess, "Popen", refuse)
    for name in ("posix_spawn", "posix_spawnp", "fork", "system", "execv", "execve", "execvp"):
        if hasattr(os, name):
            monkeypatch.setattr(os, name, refuse)
