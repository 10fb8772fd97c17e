"""The errors the command line maps to exit statuses (CONTRACT section 3)."""


class InputError(ValueError):
    """Bad input or usage: the command line reports it in one line and exits with status 2."""
