"""`with` for the bus's resources that end with `close()`: the MCAP writer, the recorder, the replayer."""

from __future__ import annotations

from typing import Any, Self


class ClosesOnExit:
    """A resource whose `with` block gives the resource itself and calls its ``close()`` when the block
    ends, however it ends.
    """

    def close(self) -> Any:
        """Release what the resource holds (each resource says what that is)."""
        raise NotImplementedError

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
