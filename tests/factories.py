"""factory-boy factories with named personas for the tests."""

import factory
from django.contrib.auth import get_user_model
from django.contrib.auth.models import User

from labs.models import Laboratory, Membership, Participant, Result, Submission
from proficiency.models import Comparison, Device, MeasurementPoint


class UserFactory(factory.django.DjangoModelFactory[User]):
    class Meta:
        model = get_user_model()
        django_get_or_create = ("username",)

    username = factory.Sequence(lambda n: f"user{n}")
    email = factory.LazyAttribute(lambda u: f"{u.username}@example.org")
    password = factory.django.Password("correct horse battery staple")


class LaboratoryFactory(factory.django.DjangoModelFactory[Laboratory]):
    class Meta:
        model = Laboratory

    name = factory.Sequence(lambda n: f"Laboratory {n}")
    country = "IT"


class MembershipFactory(factory.django.DjangoModelFactory[Membership]):
    class Meta:
        model = Membership

    user = factory.SubFactory(UserFactory)
    laboratory = factory.SubFactory(LaboratoryFactory)


class ComparisonFactory(factory.django.DjangoModelFactory[Comparison]):
    class Meta:
        model = Comparison

    code = factory.Sequence(lambda n: f"IMU-TEST-{n:02d}")
    title = factory.LazyAttribute(lambda c: f"Comparison {c.code}")


class DeviceFactory(factory.django.DjangoModelFactory[Device]):
    class Meta:
        model = Device

    comparison = factory.SubFactory(ComparisonFactory)
    name = factory.Sequence(lambda n: f"MEMS {n}")
    model = "LSM6DSR"
    nominal_sensitivity = 418.0
    tolerance = 1.0


class MeasurementPointFactory(factory.django.DjangoModelFactory[MeasurementPoint]):
    class Meta:
        model = MeasurementPoint

    device = factory.SubFactory(DeviceFactory)
    comparison = factory.SelfAttribute("device.comparison")
    axis = "X"
    frequency_hz = 10.0
    bench = "linear"
    direction = "vertical"


class ParticipantFactory(factory.django.DjangoModelFactory[Participant]):
    class Meta:
        model = Participant

    comparison = factory.SubFactory(ComparisonFactory)
    laboratory = factory.SubFactory(LaboratoryFactory)
    code = factory.Sequence(lambda n: f"L{n % 100:02d}")


class SubmissionFactory(factory.django.DjangoModelFactory[Submission]):
    class Meta:
        model = Submission

    participant = factory.SubFactory(ParticipantFactory)
    version = 1


class ResultFactory(factory.django.DjangoModelFactory[Result]):
    class Meta:
        model = Result

    submission = factory.SubFactory(SubmissionFactory)
    measurement_point = factory.SubFactory(
        MeasurementPointFactory,
        device__comparison=factory.SelfAttribute("...submission.participant.comparison"),
    )
    value = 420.0
    unit = "D/(m/s^2)"
    expanded_uncertainty = 8.0
    coverage_factor = 2.0
