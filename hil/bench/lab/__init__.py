"""A lab of benches: benches are labgrid places, reserved, acquired and released around a run.

* :mod:`.spec`     what a run asks for (``[labgrid]`` in a profile, ``--lg-place`` / ``--lg-reserve``)
* :mod:`.client`   ``labgrid-client`` as a subprocess, and what its output says (places, resources)
* :mod:`.resolve`  a place's resources → target URLs and the fault rig's coils (:class:`.resolve.Lab`)
* :mod:`.session`  reserve → wait → acquire → resolve, and release whatever happened
"""
