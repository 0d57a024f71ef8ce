"""The one exception type for errors a user can cause."""


class IsochorError(Exception):
    """A problem the user can act on: a bad file, an open mesh, a singular lattice, ...

    The message is meant to be shown as is: in a dialog by the window, on one line of
    standard error by the command line.
    """
