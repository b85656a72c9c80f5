"""The errors a user meets: every layer raises them, none of them imports anything of the
package."""


class SceneError(ValueError):
    """A scene value that is missing, misspelled or out of range, or a mesh or output folder
    that cannot be used. The message says what, where it came from and what is allowed.

    Parameters
    ----------
    message : str
        The message shown to the user.
    key : str, optional
        The dotted key it concerns (e.g. ``"contact.mu"``); None if none.
    located : bool, optional
        True once the message names the value's origin (a scene file's line or a ``--set``).
    """

    def __init__(self, message: str, key: str | None = None, located: bool = False):
        super().__init__(message)
        self.key = key
        self.located = located
