"""Exceptions the core raises on purpose.

:class:`RenderRefused` is a render the core will not start, with a message for the user that
names the cause and what to change (settings out of range, a film larger than the machine's
memory, photons over their memory cap, a missing module): Blender shows it as one ERROR
report and the command line as one line with exit code 2, without a traceback. Any other
exception out of a render is a bug and is reported with its traceback. It derives from
``ValueError`` so that code catching ``ValueError`` around a render keeps working.
"""


class RenderRefused(ValueError):
    """The core refuses to render with these settings or this scene; ``str()`` says why."""
