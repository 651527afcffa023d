"""The errors and warnings of rockjax that carry structure: `ParameterError` names the
parameter at fault, so that a front end (the command line) can name its own option for it
without rewriting the message; `ConfigurationWarning` says what rockjax did to JAX."""

from __future__ import annotations


class Placeholder:
    """A value to fill in, shown as ``<text>`` (e.g. ``Placeholder("time step in s")`` in
    the advice ``pass dt=<time step in s>``)."""

    def __init__(self, text: str):
        self.text = text

    def __repr__(self) -> str:
        return f"<{self.text}>"

    __str__ = __repr__


class ParameterError(ValueError):
    """A bad argument. `param` is the name of the API parameter at fault (``"t1"``,
    ``"scales"``, ``"units"``, ...); `message` says what is wrong without naming how to set
    it; `choices` are values that would do and `omit` whether leaving the parameter out
    would do; `value` (text, optional) the value at fault when the message is about one of
    several (``records='quakes/'``: "no record files in this folder"). ``str(e)`` gives the
    message with that advice in Python syntax (``pass units='g' or units='m/s2'``);
    `advice_for` gives it for another spelling of the parameter, such as a command-line
    option (``pass --units g or --units m/s2``).

    A subclass of `ValueError`: ``except ValueError`` catches it."""

    def __init__(self, message: str, *, param: str, choices=(), omit: bool = False,
                 value: str | None = None):
        self.message = str(message)
        self.param = param
        self.choices = tuple(choices)
        self.omit = bool(omit)
        self.value = value
        head = "" if value is None else f"{param}={value!r}: "
        super().__init__(head + self.message + self.advice_for(None))

    def advice_for(self, option: str | None) -> str:
        """The advice (``"; omit ... or pass ..."``, or ``""``) for the parameter spelled
        `option` (a command-line option such as ``"--units"``), or in Python syntax
        (``units=...``) when `option` is None."""
        def one(value):
            if option is None:
                return f"{self.param}={value!r}"
            # a boolean's option is a flag (--no-plausibility-check for False)
            return option if isinstance(value, bool) else f"{option} {value}"

        parts = []
        if self.omit:
            parts.append(f"omit {self.param}=" if option is None else f"omit {option}")
        if self.choices:
            parts.append("pass " + " or ".join(one(v) for v in self.choices))
        return f"; {' or '.join(parts)}" if parts else ""

    def __reduce__(self):  # picklable (multiprocessing, pytest-xdist)
        return (_rebuild, (self.message, self.param, self.choices, self.omit, self.value))


def _rebuild(message, param, choices, omit, value=None):
    return ParameterError(message, param=param, choices=choices, omit=omit, value=value)


class ConfigurationWarning(UserWarning):
    """rockjax changed JAX's configuration because the caller had not (float64 turned on by
    a computing entry point), or cannot give what was asked (a CPU device count after
    JAX's backend started). Call `rockjax.configure()` before any computation to choose
    explicitly and silence it."""
