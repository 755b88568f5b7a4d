"""python manage.py pt_robustness BEFORE TEST AFTER [...] — vibration robustness
(docs/interfaces.md §5).

RR, SR and SNR (docs/domain.md §8.3) and the before/after compatibility of one repetition;
several triples give the tables of mean ± sd across repetitions.  A file whose
metadata has ``zones`` holds a whole repetition by itself.  No database; exit code 2
on bad input.
"""

import json
from pathlib import Path
from typing import Any

from django.core.management.base import BaseCommand, CommandError

import proficiency
from analysis.core.groups import CoreInputError
from analysis.core.signals.records import MEMS_AXES, Record, SignalInputError, load_record
from analysis.core.signals.robustness import ZONES, Repetition, repetition, summary, zone_slices
from analysis.offline import _table, write_output
from common.sizes import counted


class Command(BaseCommand):
    help = "RR, SR, SNR and before/after compatibility of vibration robustness records."
    requires_system_checks: list[str] = []
    requires_migrations_checks = False

    def add_arguments(self, parser):
        parser.add_argument("files", nargs="+", help="BEFORE TEST AFTER, repeated per repetition")
        parser.add_argument(
            "--excited-axis", required=True, type=str.upper, choices=["X", "Y", "Z"]
        )
        parser.add_argument("--fs-hz", type=float, help="sampling rate (default: the metadata)")
        parser.add_argument("--format", choices=["json", "table"], default="table")
        parser.add_argument("--output", help="write to this file instead of standard output")

    def handle(self, *args, **opts):
        try:
            groups = _repetitions([load_record(Path(f)) for f in opts["files"]])
            reps = [_analyse(g, opts["excited_axis"], opts["fs_hz"]) for g in groups]
            table = summary([r for _, r, _ in reps])
        except CoreInputError as exc:
            raise CommandError(
                f"robustness records could not be analysed: {exc}", returncode=2
            ) from None
        doc = {
            "excited_axis": opts["excited_axis"],
            "repetitions": [{"files": files, "fs_hz": fs} | r.to_dict() for files, r, fs in reps],
            "summary": table, "software_version": proficiency.__version__,
        }  # fmt: skip
        text = json.dumps(doc, indent=2, ensure_ascii=False) + "\n"
        if opts["format"] == "table":
            text = render_table(doc)
        write_output(text, opts["output"], self.stdout)


def _repetitions(records: list[Record]) -> list[list[Record]]:
    if all("zones" in r.meta for r in records):
        return [[r] for r in records]
    if len(records) % 3:
        raise SignalInputError(
            f"{counted(len(records), 'file')} given: give BEFORE TEST AFTER for each repetition "
            "(a multiple of 3), or files whose metadata has 'zones'"
        )
    return [records[i : i + 3] for i in range(0, len(records), 3)]


def _analyse(
    group: list[Record], excited: str, fs_opt: float | None
) -> tuple[list[str], Repetition, float]:
    first = group[0]
    fs = fs_opt or first.sampling_rate()[0]
    axes = [a for a in MEMS_AXES if a in first.channels]
    for rec in group:
        if [a for a in MEMS_AXES if a in rec.channels] != axes:
            raise SignalInputError(f"{rec.name}: axes differ from {first.name} ({', '.join(axes)})")
    if len(group) == 1:
        if set(ZONES) - set(first.meta["zones"]):
            raise SignalInputError(f"{first.name}: zones must name before, test and after")
        sl = zone_slices(first, {z: first.meta["zones"][z] for z in ZONES}, fs)
        parts = [first.data[[first.channels.index(a) for a in axes], sl[z]] for z in ZONES]
    else:
        parts = [r.data[[r.channels.index(a) for a in axes]] for r in group]
    before, test, after = parts
    rep = repetition(before, test, after, axes=axes, excited=excited, fs_hz=fs)
    return [r.name for r in group], rep, fs


def _num(v: float | None) -> Any:
    return "—" if v is None else v


def render_table(doc: dict[str, Any]) -> str:
    axes = list(doc["repetitions"][0]["rr_db"])
    parts = [f"excited axis {doc['excited_axis']}, proficiency {doc['software_version']}"]
    for key, title in (("rr_db", "RR / dB"), ("sr_db", "SR / dB"), ("snr_db", "SNR / dB")):
        rows = [[i + 1, *[_num(r[key][a]) for a in axes]] for i, r in enumerate(doc["repetitions"])]
        s = doc["summary"][key]
        rows.append(["mean", *[_num(s[a]["mean"]) for a in axes]])
        rows.append(["sd", *[_num(s[a]["sd"]) for a in axes]])
        parts += ["", title, _table(["repetition", *axes], rows)]
    parts += ["", "BEFORE / AFTER (En of the means with k = 2; F test of the variances)"]
    parts.append(_table(
        ["repetition", "axis", "mean before", "sd before", "mean after", "sd after", "En",
         "means", "F", "sds"],
        [[i + 1, a, b["mean_before"], b["sd_before"], b["mean_after"], b["sd_after"],
          b["en_mean"], "compatible" if b["mean_compatible"] else "NOT compatible", b["f_ratio"],
          "compatible" if b["sd_compatible"] else "NOT compatible"]
         for i, r in enumerate(doc["repetitions"]) for a, b in r["before_after"].items()],
    ))  # fmt: skip
    return "\n".join(parts) + "\n"
