"""The scan tests' check that a call is refused with a given error class and code, its message
naming the problem."""
import pytest


def refused(cls, code, *words, call) -> str:
    """call() raises `cls` with `.code == code` and every one of `words` in its message; returns
    the message."""
    with pytest.raises(cls) as info:
        call()
    assert info.value.code == code, (type(info.value), info.value.code)
    for w in words:
        assert w in str(info.value), (w, str(info.value))
    return str(info.value)
