"""python manage.py load_demo — the demo comparison IMU-2024-DEMO, the open call IMU-2025-CALL,
the published round before them, IMU-2023-DEMO, and the analysed two-kit round of magnitude,
phase and angular-rate points, IMU-2025-KITS (idempotent)."""

from django.core.management.base import BaseCommand

from coordination.demo import load_demo


class Command(BaseCommand):
    help = (
        "Create the demo comparison IMU-2024-DEMO with 12 laboratories, the round "
        "IMU-2025-CALL with its call for participation open, and the same laboratories' "
        "published round IMU-2023-DEMO, their history, and the analysed two-kit round "
        "IMU-2025-KITS of magnitude, phase and angular-rate points (idempotent)."
    )

    def add_arguments(self, parser):
        parser.add_argument(
            "--password",
            help="Password for the demo accounts created now (default: a random one each).",
        )

    def handle(self, *args, password=None, **options):
        summary = load_demo(password=password)
        c = summary.comparison
        self.stdout.write(
            f"Demo comparison {c.code}: {c.devices.count()} devices, "
            f"{c.measurement_points.count()} measurement points, "
            f"{c.participants.count()} participants."
        )
        call = summary.call
        if call is not None:
            pending = call.enrolments.filter(status="pending").count()
            self.stdout.write(
                f"Open call {call.code}: {call.measurement_points.count()} measurement points, "
                f"{pending} pending application{'' if pending == 1 else 's'} (lab03-manager "
                "for the linear bench, the curvilinear laboratory's software for the "
                "curvilinear one; the coordinator accepts or declines them)."
            )
        previous = summary.previous
        if previous is not None:
            self.stdout.write(
                f"Earlier round {previous.code}: {previous.measurement_points.count()} "
                f"measurement points, {previous.participants.count()} participants, "
                f"{previous.get_status_display().lower()} (its publication is a job, done "
                "when the task queue runs it; each laboratory's history is at /lab/history/)."
            )
        kits = summary.kits_round
        if kits is not None:
            self.stdout.write(
                f"Kit round {kits.code}: {kits.measurement_points.count()} measurement points "
                "(magnitude, phase, angular rate), "
                f"{kits.participants.count()} participants, two kits (Kit B's IMU 1 gyroscope "
                f"drifting, Kit B on its way back to the pilot), "
                f"{kits.get_status_display().lower()}."
            )
        if summary.created_users:
            self.stdout.write("Demo logins (shown once; write them down):")
            for username, pw in summary.created_users.items():
                self.stdout.write(f"  {username:16s} {pw}")
        if summary.existing_users:
            self.stdout.write(
                "Existing demo accounts kept their passwords: "
                + ", ".join(summary.existing_users)
                + " (change one with: python manage.py changepassword USERNAME)."
            )
