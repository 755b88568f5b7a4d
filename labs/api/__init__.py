"""REST API for lab software (docs/interfaces.md §3): ``/api/v1/``.

Edges only: authentication (``Authorization: Api-Key <key>`` or the session),
scoping of what the caller may see, throttling, serialisers and thin views that
call the one submission service path in :mod:`labs.services`.
"""
