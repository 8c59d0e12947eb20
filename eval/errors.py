"""`EvalError`: the one exception eval raises for a bad configuration, and `RunInterrupted` (Ctrl-C after the
finished episodes were written). A leaf module: it imports nothing."""


class EvalError(ValueError):
    """A bad configuration found before any rollout (unknown env id or policy, existing --out, ...), or a file
    that cannot be written (a full disk).

    The CLIs print it as `mobman-eval <command>: error: <message>` and exit with code 2; the message names the bad
    value, what is accepted and the fix. `resume`: the options that continue the command where it stopped (e.g.
    `("--out", "runs/x", "--resume")` after a full disk); the CLI then prints the exact command line that resumes
    (the user's own, with these options in place of any earlier values of them)."""

    def __init__(self, message: str = "", resume: tuple[str, ...] = ()):
        super().__init__(message)
        self.resume = tuple(resume)


class RunInterrupted(KeyboardInterrupt):
    """Ctrl-C stopped a run after its finished episodes were written (the unfinished ones are marked
    "interrupted"); the CLIs print the message and exit with code 130."""
