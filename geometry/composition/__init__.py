"""Exact functional composition ``outer(inner(.))`` (Elber 2017, Section 2, Eqs. 4-7; Massarwi et al. 2018,
Eq. 3): the general Bernstein path (:mod:`.core`, :mod:`.bezier`), the fast paths for affine pieces and boxes
(:mod:`.affine`, :mod:`.boxes`), curves crossing knot lines (:mod:`.curves`), exact products
(:mod:`.products`) and degree reduction of the results (:mod:`.reduction`)."""
