"""The print file of a design (`acl export`, docs/export.md).

:mod:`acl.export.solid` turns the resolved design into solids (manifold3d's exact booleans),
:mod:`acl.export.measure` measures the exported meshes against the design (cavity volumes, orifice
radii, beam sections and lengths), :mod:`acl.export.files` writes STL, 3MF and OBJ atomically,
:mod:`acl.export.arrange` lays print variants out on one substrate and :mod:`acl.export.preview`
renders the exported solid.  Everything here needs the `cad` extra (manifold3d, trimesh) and is
imported only by the command that uses it.
"""
