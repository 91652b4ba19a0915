"""The overwrite policy on the command line: refusals are usage errors, replacements said.

The policy itself is :mod:`wheelcal.io.ownership` (docs/guide/outputs.md,
"Overwriting"); every command that writes claims its outputs here before any
work, so a refusal costs nothing.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Sequence

from wheelcal.cli.errors import UsageError

#: Where the policy is explained (every writing command's --force help points here).
POLICY_DOC = "docs/guide/outputs.md#overwriting"
#: The ``--force`` help of every command that writes.
FORCE_HELP = (
    "also replace outputs wheelcal did not write from these inputs (a user's file, a "
    "recording); never an input itself or a device, folder or FIFO. Without it only "
    f"wheelcal's own earlier outputs of the same inputs are replaced ({POLICY_DOC})"
)
#: Shown at the end of every writing command's --help.
POLICY_EPILOG = (
    "Overwriting: an existing output is replaced only if wheelcal wrote it from the same "
    "input (the command says so) or with --force; an input, a folder, a device or a FIFO "
    f"is never written over. See {POLICY_DOC}."
)
#: More replacement notes than this are summed up in one line.
_NOTES_SHOWN = 3


def claim(outputs: Sequence, force: bool, command: str) -> bool:
    """Claim ``outputs`` (:class:`~wheelcal.io.ownership.Output`) or raise UsageError (exit 2).

    Prints a note per file replaced (a few, then a count) on stderr.  Returns
    whether any of them exists (then the writer replaces, else it must not clobber).
    """
    from wheelcal.io import OutputRefusedError, claim_outputs

    try:
        notes = claim_outputs(outputs, force)
    except OutputRefusedError as exc:
        raise UsageError(str(exc)) from None
    say(notes, command)
    return any(os.path.lexists(out.path) for out in outputs)


def say(notes: Sequence[str], command: str) -> None:
    """The replacement notes, on stderr (a few, then how many more)."""
    for note in notes[:_NOTES_SHOWN]:
        print(f"wheelcal {command}: note: {note}", file=sys.stderr)
    if len(notes) > _NOTES_SHOWN:
        print(
            f"wheelcal {command}: note: and {len(notes) - _NOTES_SHOWN} more earlier outputs "
            "of the same inputs replaced",
            file=sys.stderr,
        )
