"""Multi-patch models: placed patches and the interfaces that glue them (:mod:`.multipatch`), their points
in bulk (:mod:`.placed_points`, :mod:`.chain`), faces in contact (:mod:`.contact`), and conforming sampling
into one welded mesh (:mod:`.sampling`)."""
