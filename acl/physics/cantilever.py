"""The cantilever laws under the names the fit imports (acl.fit.beam, acl.physics.effects): all live in acl.physics.beams.

``eq1_deflection`` here is paper Eq. (1) in the linear-beam integrals (c_D, c_T) of a graded beam,
:func:`acl.physics.beams.eq1_profile_deflection`; ``elastica_deflection`` the table of the one elastica
solver, :func:`acl.physics.beams.elastica_tip`.
"""
from acl.physics.beams import (  # noqa: F401
    L_REF,
    P_MAX,
    elastica_deflection,
    elastica_table,
    stiffness_integrals,
)
from acl.physics.beams import eq1_profile_deflection as eq1_deflection  # noqa: F401
