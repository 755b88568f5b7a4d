"""The coordinator's side: the coordinator pages, the setup API (devices, measurement-point
grid, invitations) and the demo data. The top layer: it may import analysis, labs,
proficiency and common; none of them imports it (docs/architecture.md §5)."""
