"""The discrete setting every physics shares (:mod:`.setting`): spaces and quadrature, face geometry, fields at
Gauss points, the regularity proof, NURBS weights, interface constraints resolved into one prolongation,
connected components, Dirichlet projection, the reduced linear system, point location and the spline
structure the solvers use."""
