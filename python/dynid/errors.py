"""The exceptions of dynid.

Every error carries the runtime's ``code`` (as the command line prints it, e.g.
``dynid::data::non_finite``) and a ``help`` line saying what to do.
"""

from typing import Any as _Any, Dict as _Dict, List as _List, Optional as _Optional

__all__ = ["DynidError", "CompileError", "DataError", "ParameterError", "OptionError"]


class DynidError(Exception):
    """An error of dynid: a model, data or option it refuses, or a run that failed."""

    code: str = ""
    help: str = ""


class CompileError(DynidError, ValueError):
    """A model that does not compile.

    ``str(err)`` is the rendered diagnostic of every error in the source (file, line,
    column, the offending text and a help line); ``line`` and ``column`` (1-based) locate
    the first error, ``errors`` lists all of them as dicts (``code``, ``message``, ``help``,
    ``line``, ``column``).
    """

    rendered: str = ""
    line: _Optional[int] = None
    column: _Optional[int] = None
    errors: _List[_Dict[str, _Any]] = []


class DataError(DynidError, ValueError):
    """Data that cannot be used, naming where the problem is.

    ``level`` is the 1-based position of the level in the list given, ``column`` the
    column's name and ``sample`` the 1-based sample number, where they apply (else None).
    """

    level: _Optional[int] = None
    column: _Optional[str] = None
    sample: _Optional[int] = None


class ParameterError(DynidError, ValueError):
    """A parameter value the call refuses: a name that is not an unknown parameter of the
    model, a known parameter (its value is part of the model), a value that is not a finite
    number, or an unknown parameter without a value where a simulation needs one."""


class OptionError(DynidError, ValueError):
    """A setting of a call that is out of range (``alpha`` not between 0 and 1, a shooting
    interval that is not a positive duration, a refinement weight of an unknown signal,
    a simulation above the step limit, ...)."""
