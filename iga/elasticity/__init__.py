"""Small-strain linear elasticity and thermal stress (Elber 2017, Section 3, Fig. 12): the problem
(:mod:`.problem`), its coefficient fields and volume assembly, vector data, the rigid modes a support leaves
free, the thermal strain, and the solution's post-processing."""
