"""The OpenAPI schema: operations grouped by tag, and the error responses (drf-spectacular).

Operations that name no tag of their own are grouped by what their path does
(:class:`AutoSchema`), so that Swagger UI shows the coordinator's operations under
headings rather than under the version prefix.

Every ``/api/v1/`` view answers errors through :func:`common.errors.api_exception_handler`
with the same ``Error`` body (docs/interfaces.md §3), but most views only declare their success
response. This hook documents the error statuses any of them can return, so that the
schema matches what clients receive (checked by ``tests/security/test_schema_fuzz.py``).
"""

from __future__ import annotations

from typing import Any

from drf_spectacular import openapi

#: (path fragment, tag) for operations without a tag of their own: the first match counts
PATH_TAGS = (
    ("/applications", "enrolment"),
    ("/calls", "enrolment"),
    ("/report-notes", "reports"),
    ("/reports", "reports"),
    ("/analysis-runs", "analysis runs"),
    ("/scores", "scores and compatibility"),
    ("/compatibility", "scores and compatibility"),
    ("/doe-covariance", "scores and compatibility"),
    ("/devices", "round set-up (coordinators)"),
    ("/measurands/generate", "round set-up (coordinators)"),
    ("/participants", "round set-up (coordinators)"),
    ("/transition", "round life cycle (coordinators)"),
    ("/publish", "round life cycle (coordinators)"),
    ("/publications", "round life cycle (coordinators)"),
    ("/decision", "review (coordinators)"),
    ("/check-requests", "review (coordinators)"),
    ("/accept-complete", "review (coordinators)"),
)


class AutoSchema(openapi.AutoSchema):
    """drf-spectacular's schema, tagging untagged operations by :data:`PATH_TAGS`."""

    def get_tags(self) -> list[str]:
        for fragment, tag in PATH_TAGS:
            if fragment in self.path:
                return [tag]
        return super().get_tags()


ERROR_REF = {"$ref": "#/components/schemas/Error"}
#: status -> description, for every operation
COMMON = {
    "400": "Bad input; `errors` lists every bad row and field",
    "401": "No credentials, or an invalid, revoked or expired API key",
    "403": "Authenticated, but without the role this needs",
    "404": "No such object, or not visible to you (also other laboratories')",
    "409": "The object's state does not allow this",
    "429": "Too many requests; retry after the Retry-After header's seconds",
}
#: only where a request body is read
WITH_BODY = {
    "413": "The request body or the file is too large",
    "415": "The request body's Content-Type is not one this operation reads",
}


def error_responses(result: dict[str, Any], generator: Any, request: Any, public: Any) -> dict:
    """Add the shared error responses that an operation does not declare itself."""
    for path, operations in result.get("paths", {}).items():
        if not path.startswith("/api/v1/"):
            continue
        for operation in operations.values():
            statuses = COMMON | (WITH_BODY if "requestBody" in operation else {})
            responses = operation.setdefault("responses", {})
            for status, response in responses.items():
                # errors are always JSON, also from views that render CSV or XLSX
                content = response.get("content", {})
                if status >= "400" and ERROR_REF in [c.get("schema") for c in content.values()]:
                    response["content"] = {"application/json": {"schema": ERROR_REF}}
            for status, description in statuses.items():
                responses.setdefault(
                    status,
                    {"content": {"application/json": {"schema": ERROR_REF}},
                     "description": description},
                )  # fmt: skip
    return result
