"""The platform under every app: the error hierarchy and its HTTP mapping, request
protections, the API's parsers, pagination, filters and rendering, logs, health, cache, the
superuser-only admin site, password reset, job liveness. It imports no app
(docs/architecture.md §5)."""
