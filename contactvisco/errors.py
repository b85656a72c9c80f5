"""The errors a user meets: every layer raises them, none of them imports anything of the
package."""


class SceneError(ValueError):
    """A scene value that is missing, misspelled or out of range. `key` is the dotted key it
    concerns (None if none); `located` is True once the message names the value's origin."""

    def __init__(self, message: str, key: str | None = None, located: bool = False):
        super().__init__(message)
        self.key = key
        self.located = located
