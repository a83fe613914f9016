"""The library's own exception type.

Every error caused by the user's input (a missing file, a malformed rig, an
impossible parameter) is raised as :class:`SlitcliError` with a one-line message
that names the file or parameter and says how to fix it. The command line turns it
into exit status 2; anything else is an internal error (exit status 1).

Library messages speak of parameters by their Python names (``bin_deg``,
``max_dt_s``), the names a library user passes; :attr:`SlitcliError.param` lists
them, and the command line rewrites them into its own option names once
(:func:`slitcli.cli.user_message`).
"""

from __future__ import annotations


class SlitcliError(Exception):
    """Bad input: the message is one line naming what is wrong and the fix.

    Parameters
    ----------
    message : str
        One line. A parameter is named as in the library (``bin_deg 20 is out of
        range; give 0.05-10 degrees``).
    param : str or tuple of str, optional
        The parameter name(s) the message speaks of, as written in it.

    Examples
    --------
    >>> e = SlitcliError("bin_deg 20 is out of range; give 0.05-10 degrees", param="bin_deg")
    >>> e.params
    ('bin_deg',)
    """

    def __init__(self, message: str, *, param: str | tuple[str, ...] | None = None) -> None:
        super().__init__(message)
        self.param = param

    @property
    def params(self) -> tuple[str, ...]:
        """The named parameters as a tuple (empty when the message names none)."""
        if self.param is None:
            return ()
        return (self.param,) if isinstance(self.param, str) else tuple(self.param)
