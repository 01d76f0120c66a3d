"""UserError: a mistake of the person running virtmech (a bad scenario, flag or path), as
opposed to a bug. The command line reports it as one message on stderr and exits with 2;
library callers catch it (or ValueError, for ScenarioError) like any exception."""

from __future__ import annotations

__all__ = ["UserError"]


class UserError(Exception):
    """A mistake in the input: its message names the file, key or flag, the value found and
    what was expected. Several mistakes found at once are kept in `messages`."""

    def __init__(self, *messages: str):
        self.messages = [str(m) for m in messages] or ["invalid input"]
        super().__init__("\n".join(self.messages))
