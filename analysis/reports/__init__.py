"""PT reports (ISO/IEC 17043, docs/domain.md §9): plain data → PDF, issuing, access.

``data`` and ``render`` (+ ``charts``) import no Django; ``assemble`` reads the ORM into
``data``; ``services`` stores issued reports; ``tasks``, ``api`` and ``views`` are the edges.
"""
