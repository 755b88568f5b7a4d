"""python manage.py pt_sensitivity FILE — sensitivity from one raw record (docs/interfaces.md §5).

No database or server: the record is read by ``analysis.core.signals.records`` and
analysed by ``analysis.core.signals`` (docs/domain.md §8.1–8.2).  Exit code 2 on bad input.
"""

import json
from pathlib import Path
from typing import Any

from django.core.management.base import BaseCommand, CommandError

import proficiency
from analysis.core.groups import CoreInputError
from analysis.core.signals.records import load_record
from analysis.core.signals.results import SensitivityResult
from analysis.core.signals.sensitivity import METHODS, record_analysis
from analysis.offline import _table, write_output


class Command(BaseCommand):
    help = "Sensitivity per axis, with its uncertainty budget, from one raw time series."
    requires_system_checks: list[str] = []
    requires_migrations_checks = False

    def add_arguments(self, parser):
        parser.add_argument("file", help="raw record: CSV, or int16 with a FILE.json sidecar")
        parser.add_argument("--sidecar", help="metadata JSON (default: FILE.json if present)")
        parser.add_argument("--reference", help="record with the ref or encoder_rad channel")
        parser.add_argument("--reference-sidecar", help="metadata JSON of the reference record")
        parser.add_argument("--bench", choices=["linear", "curvilinear"])
        parser.add_argument("--frequency-hz", type=float, help="excitation frequency f")
        parser.add_argument("--method", choices=METHODS, default="sine-fit")
        parser.add_argument("--format", choices=["json", "table"], default="table")
        parser.add_argument("--output", help="write to this file instead of standard output")

    def handle(self, *args, **opts):
        overrides = {"bench": opts["bench"], "frequency_hz": opts["frequency_hz"]}
        try:
            mems = load_record(Path(opts["file"]), _path(opts["sidecar"]), overrides)
            reference = None
            if opts["reference"]:
                reference = load_record(
                    Path(opts["reference"]), _path(opts["reference_sidecar"]),
                    {"frequency_hz": mems.meta.get("frequency_hz")},
                )  # fmt: skip
            result = record_analysis(mems, reference, opts["method"])
        except CoreInputError as exc:
            raise CommandError(
                f"{opts['file']} could not be analysed: {exc}", returncode=2
            ) from None
        doc = result.to_dict() | {"software_version": proficiency.__version__}
        if opts["format"] == "json":
            text = json.dumps(doc, indent=2, ensure_ascii=False) + "\n"
        else:
            text = render_table(result, doc)
        write_output(text, opts["output"], self.stdout)


def _path(value: str | None) -> Path | None:
    return Path(value) if value else None


def render_table(result: SensitivityResult, doc: dict[str, Any]) -> str:
    accel = [a for a in doc["axes"] if a["sensor"] == "accelerometer"]
    parts = [
        f"{result.bench} bench, f = {result.frequency_hz:g} Hz, method {result.method}, "
        f"proficiency {doc['software_version']}",
        f"sampling rate fs = {result.fs_hz:.6f} Hz, u(fs) = {result.u_fs_hz:.3g} Hz",
        f"reference: {result.reference_source}",
        *[f"note: {n}" for n in result.notes],
        "",
        _table(
            ["axis", "direction", "f/Hz", "output", "reference m/s²", "S", "u(S)", "U(S)", "k",
             "status"],
            [[a["axis"], a["direction"], f"{a['analysis_frequency_hz']:g}", a["output_amplitude"],
              a["reference_amplitude_m_s2"], a["sensitivity"], a["standard_uncertainty"],
              a["expanded_uncertainty"], a["coverage_factor"], a["status"]]
             for a in accel],
        ),
        *_phase_table(accel),
        *_rate_table([a for a in doc["axes"] if a["sensor"] == "gyroscope"]),
    ]  # fmt: skip
    for a in doc["axes"]:
        if a["note"]:
            parts.append(f"{a['axis']}: {a['note']}")
        if a["budget"]:
            nu = "∞" if a["dof_eff"] is None else f"{a['dof_eff']:.1f}"
            parts += ["", f"BUDGET {a['axis']} ({a['direction']}): ν_eff = {nu}"]
            parts.append(_table(
                ["component", "type", "value", "u", "c", "|c|·u", "ν"],
                [[c["name"], c["type"], c["value"], c["standard_uncertainty"],
                  c["sensitivity_coefficient"], c["contribution"],
                  "∞" if c["dof"] is None else f"{c['dof']:.0f}"] for c in a["budget"]],
            ))  # fmt: skip
    return "\n".join(parts) + "\n"


def _phase_table(axes: list[dict[str, Any]]) -> list[str]:
    """The phase of each accelerometer axis, or why there is none (docs/domain.md §12.1)."""
    if not axes:
        return []
    return ["", "PHASE against the reference", _table(
        ["axis", "φ/°", "u(φ)/°", "note"],
        [[a["axis"], a["phase_deg"], a["u_phase_deg"], a["phase_note"]] for a in axes],
    )]  # fmt: skip


def _rate_table(axes: list[dict[str, Any]]) -> list[str]:
    """The gyroscope axes: angular-rate sensitivity per °/s and per rad/s, and phase to ω."""
    if not axes:
        return []
    return ["", "ANGULAR RATE (gyroscope, ω = dθ/dt of the encoder)", _table(
        ["axis", "direction", "f/Hz", "ω0 °/s", "S per °/s", "u(S)", "U(S)", "k", "S per rad/s",
         "φ/°", "u(φ)/°", "status"],
        [[a["axis"], a["direction"], f"{a['analysis_frequency_hz']:g}", a["omega_deg_s"],
          a["sensitivity"], a["standard_uncertainty"], a["expanded_uncertainty"],
          a["coverage_factor"], a["sensitivity_per_rad_s"], a["phase_deg"], a["u_phase_deg"],
          a["status"]] for a in axes],
    ), *[f"{a['axis']}: {a['phase_note'] or a['note']}" for a in axes
         if a["phase_note"] or a["note"]]]  # fmt: skip
