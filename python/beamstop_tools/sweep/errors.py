"""The one exception the sweep tool raises for bad input: its message names
the field, the value and what is allowed, and the command line prints it
without a traceback."""


class SweepError(ValueError):
    pass
