"""The body and its path dynamics: segments and limits (:mod:`.body`), foot contacts
(:mod:`.contacts`), derivatives of the path (:mod:`.path`), rigid-body kernels (:mod:`.tree`), the
contact basis (:mod:`.contact_basis`) and a, b, c, N per frame (:mod:`.dynamics`).
"""
