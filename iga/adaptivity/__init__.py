"""Adaptive refinement by tiles: an octree of patches per patch of the model (:mod:`iga.adaptivity.tree`), a
residual error estimate per element and patch (:mod:`iga.adaptivity.estimator`) and the loop that refines where
the estimate is largest (:mod:`iga.adaptivity.loop`)."""
