"""Properties of a map: is its Jacobian never zero (:mod:`.regularity`, :mod:`.sign_net`), bounds on its
local scale (:mod:`.scale`), and the parameters of physical points (:mod:`.inversion`)."""
