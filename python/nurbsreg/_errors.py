"""Exceptions and warnings of nurbsreg: the CLI's errors, with the same one-line messages."""


class InputError(ValueError):
    """Bad input: an unreadable, malformed or invalid file or model (the CLI's exit status 3).

    The message names the file and the problem, e.g. ``scan.xyz: line 12: expected 3 numbers``.
    """


class OutputError(OSError):
    """A file could not be written (the CLI's exit status 1); no partial file is left behind."""


class AlignmentError(RuntimeError):
    """An alignment that gave no pose to use (ICP lost its correspondences or its normal
    equations broke down): the CLI's ``align`` exits 1 with this message. ``result`` holds the
    :class:`AlignmentResult` (termination, history, ...) for a closer look."""

    def __init__(self, message, result=None):
        super().__init__(message)
        self.result = result


class NurbsregWarning(UserWarning):
    """What the CLI prints as a warning: scan and model of very different sizes, an alignment
    that ran out of iterations or leaves directions unconstrained, faces missing from a CAD
    model."""
