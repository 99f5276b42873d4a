"""Lint rules, one module per family: acoustics (ACL1xx), forces (ACL2xx), latches (ACL3xx),
beams (ACL4xx), fabrication (ACL5xx), declarations (ACL6xx)."""
