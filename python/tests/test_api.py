"""The package's public surface: every name it exports is there and says
what it does (Python's help() shows the Rust doc comment as the docstring;
one put above a helper instead leaves the function with none)."""

import mocomp


def test_every_exported_function_has_a_docstring():
    assert mocomp.__all__
    for name in mocomp.__all__:
        thing = getattr(mocomp, name)
        if callable(thing):
            assert (thing.__doc__ or "").strip(), f"mocomp.{name} has no docstring"
