"""Steady heat conduction (Massarwi et al. 2018, Eq. 9): the problem (:mod:`.problem`), its coefficients,
its weak form and volume assembly, and the solution's post-processing (:mod:`.solution`)."""
