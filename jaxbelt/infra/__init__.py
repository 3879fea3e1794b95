"""Infrastructure the physics does not see: compiled programs kept between processes
(:mod:`~jaxbelt.infra.programs`), configurations sharded over devices and processes
(:mod:`~jaxbelt.infra.sharding`), the resumable sweep store (:mod:`~jaxbelt.infra.store`), and the
one way a typed result turns into JSON (:mod:`~jaxbelt.infra.results`).
Below every other layer; imports nothing of jaxbelt."""
