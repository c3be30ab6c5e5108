"""The application edge: the ``iga`` command line (:mod:`.cli`), pipeline configurations checked whole before
any work (:mod:`.config` and its sections), the pipeline that builds, solves and writes (:mod:`.pipeline`,
:mod:`.pipeline_build`), the maps a pipeline may name, and process-wide memory settings (:mod:`.memory`)."""
