"""Cantilever deflection laws of the fit (moved to :mod:`acl.physics.cantilever`, shared with the analysis)."""
from acl.physics.cantilever import (L_REF, P_MAX, elastica_deflection, elastica_table, eq1_deflection,  # noqa: F401
                                    stiffness_integrals)
