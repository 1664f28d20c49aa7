"""Python messages name keywords, never flags: every exception a test of the compiled module expects
(pytest.raises of a ValueError, TypeError, OSError or KeyboardInterrupt) is checked for a command-line
flag outside quotes and outside a command line quoted in prose ("msid fit --method multi"), the words
the extension itself leaves alone (msid._msid._python_words is the identity on such a message)."""
import re

import pytest

# a flag as the command line writes one: "--" and a lower-case letter, after a space, '(' or ',' or first
_FLAG = re.compile(r"(^|[\s(,/])--[a-z]")
CHECKED = (ValueError, TypeError, OSError, KeyboardInterrupt)


def flag_words(message, python_words):
    """The message's flags that Python's words would not hold (empty: it names keywords only)."""
    if not _FLAG.search(message):
        return ""
    return message if python_words(message) != message else ""


class _Checking:
    """pytest.raises' context, checking the message of the exception it caught."""

    def __init__(self, cm, python_words, seen):
        self.cm, self.words, self.seen = cm, python_words, seen

    def __enter__(self):
        self.info = self.cm.__enter__()
        return self.info

    def __exit__(self, *exc):
        suppressed = self.cm.__exit__(*exc)
        e = exc[1]
        if suppressed and isinstance(e, CHECKED):
            self.seen.append(str(e))
            bad = flag_words(str(e), self.words)
            assert not bad, f"a Python message names a command-line flag: {bad!r}"
        return suppressed


def checking_raises(real, python_words, seen):
    """pytest.raises that also checks the caught message (the context form; the call form too)."""
    def raises(expected, *args, **kw):
        if args:   # pytest.raises(E, f, *args): the call form
            info = real(expected, *args, **kw)
            if isinstance(info.value, CHECKED):
                seen.append(str(info.value))
                bad = flag_words(str(info.value), python_words)
                assert not bad, f"a Python message names a command-line flag: {bad!r}"
            return info
        return _Checking(real(expected, **kw), python_words, seen)
    return raises


@pytest.fixture
def keyword_messages(monkeypatch):
    """For the compiled module's tests: every bad-input case's message is checked (conftest.py)."""
    from msid import _msid
    seen = []
    monkeypatch.setattr(pytest, "raises", checking_raises(pytest.raises, _msid._python_words, seen))
    yield seen
