"""Exceptions and warnings of nurbsreg: the CLI's errors, with the same one-line messages."""


class InputError(ValueError):
    """Bad input: an unreadable, malformed or invalid file or model (the CLI's exit status 3).

    The message names the file and the problem, e.g. ``scan.xyz: line 12: expected 3 numbers``.
    """


class OutputError(OSError):
    """A file could not be written (the CLI's exit status 1); no partial file is left behind."""


class AlignmentError(RuntimeError):
    """An alignment that gave no pose to use (ICP lost its correspondences or its normal
    equations broke down, the global stage found no hypothesis, or the fit is poor): the CLI's
    ``align`` exits 1 with this message. ``result`` holds the :class:`AlignmentResult`
    (termination, history, report, ...) for a closer look."""

    def __init__(self, message, result=None):
        super().__init__(message)
        self.result = result


class PoorFitError(AlignmentError):
    """The alignment ran, but its fit verdict is poor (too few scan points within 3 x the scan's
    noise of the model, or too little of the model covered) and ``accept_poor`` was not set: the
    CLI's ``align`` without ``--accept-poor`` exits 1 with this message. ``result.fit`` holds the
    verdict and its numbers; ``result`` the whole pose and report."""


class NurbsregWarning(UserWarning):
    """What the CLI prints as a warning: scan and model of very different sizes, an alignment
    that ran out of iterations or leaves directions unconstrained, faces missing from a CAD
    model."""
