"""Effective properties of periodic tiles by first-order homogenisation (:mod:`.cells`) and graded macro models
tabulated over a tile family (:mod:`.macro`)."""
