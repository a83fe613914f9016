"""The library's own exception type.

Every error caused by the user's input (a missing file, a malformed rig, an
impossible parameter) is raised as :class:`SlitcliError` with a one-line message
that names the file or option and says how to fix it. The command line turns it
into exit status 2; anything else is an internal error (exit status 1).
"""


class SlitcliError(Exception):
    """Bad input: the message is one line naming what is wrong and the fix."""
