"""Where the tools write: their own output folder, and the repository's ``docs/`` only when asked.

Every command writes everything into one folder, ``out/<command>/`` unless ``--output`` names
another. A report is laid out as ``docs/`` lays it out (the markdown at the top, its figures in
a subfolder), so its links work where it is written. ``--update-docs`` then copies the tracked
files (the report and the figures ``docs/`` shows) from that folder into ``docs/``: nothing else
in the repository is ever written.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

# The repository's docs/ (the tools run from a source checkout; the extension archive has none).
DOCS = Path(__file__).resolve().parents[1] / "docs"


def default_output(command):
    """The default output folder of ``command``: ``out/<command>``."""
    return os.path.join("out", command)


def add_output_arguments(parser, command, tracked=None):
    """``--output`` (default ``out/<command>``) and, for a command whose report ``docs/``
    shows, ``--update-docs`` (``tracked`` says which files it copies)."""
    parser.add_argument("--output", default=default_output(command), metavar="DIR",
                        help="folder that receives every file this command writes "
                             "(default: %(default)s)")
    if tracked:
        parser.add_argument("--update-docs", action="store_true",
                            help=f"also copy {tracked} from the output folder into the "
                                 f"repository's docs/ (tracked files: only when asked)")


def publish(output, files, docs=None, log=print):
    """Copy ``files`` (paths relative to ``output``) to the same paths under ``docs``
    (default :data:`DOCS`), each by an atomic replace. Returns the paths written."""
    docs = Path(DOCS if docs is None else docs)
    written = []
    for rel in files:
        src, dst = Path(output) / rel, docs / rel
        if not src.is_file():
            raise FileNotFoundError(f"{src} was not written, so docs/{rel} is left as it is")
        dst.parent.mkdir(parents=True, exist_ok=True)
        tmp = dst.with_name(dst.name + ".tmp")
        shutil.copyfile(src, tmp)
        os.replace(tmp, dst)
        written.append(str(dst))
    log(f"updated {len(written)} files in {docs}: {', '.join(files)}")
    return written
