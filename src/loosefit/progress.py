"""Progress bars fed by the ``progress(done, total)`` callbacks loosefit's long jobs take.

``tqdm`` is imported when a bar opens, not with this module.
"""

from __future__ import annotations


class tqdm_bar:  # noqa: N801 - reads like the tqdm call it wraps
    """A tqdm bar fed by ``progress(done, total)`` callbacks."""

    def __init__(self, desc: str, unit: str) -> None:
        from tqdm import tqdm

        self.bar = tqdm(total=0, desc=desc, unit=unit)

    def progress(self, done: int, total: int) -> None:
        if self.bar.total != total:
            self.bar.total = total
        self.bar.update(done - self.bar.n)

    def close(self) -> None:
        self.bar.close()


class StageBars:
    """One tqdm bar per stage of a long job, fed by ``progress(stage, done, total)``
    callbacks: a stage's bar opens when it starts (its count, rate and time to go) and stays
    on screen, with its time, when the next one starts."""

    def __init__(self, prefix: str, units: dict[str, str]) -> None:
        self.prefix, self.units = prefix, units
        self.stage, self.bar = None, None

    def progress(self, stage: str, done: int, total: int) -> None:
        from tqdm import tqdm

        if stage != self.stage:
            self.close()
            self.stage = stage
            one = "{desc}: done in {elapsed}" if total == 1 else None  # no rate for one step
            self.bar = tqdm(
                total=total or None,
                desc=f"{self.prefix}: {stage}",
                unit=self.units.get(stage, "step"),
                bar_format=one,
            )
        if total and self.bar.total != total:
            self.bar.total = total
        self.bar.update(done - self.bar.n)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
        self.stage, self.bar = None, None
