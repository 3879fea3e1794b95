"""Infrastructure the physics does not see: compiled programs kept between processes
(:mod:`~jaxbelt.infra.programs`), configurations sharded over devices and processes
(:mod:`~jaxbelt.infra.sharding`), and the resumable sweep store (:mod:`~jaxbelt.infra.store`).
Below every other layer; imports nothing of jaxbelt."""
