"""template_store: the offline phase (§II-A) as a service — CAD meshes -> 3D templates, served on demand.

For every target (the T-72 and the simulator's confusers, plus any `pipeline.target_meshes` file) and
descriptor it builds the template (dense surface sampling, hidden point removal from the aerial view(s),
uniform subsampling at 0.3 m, description), caches it on disk keyed by the mesh's content and every parameter,
and answers queries on `atr/templates/{target}/{descriptor}`. The configured descriptor's templates are built
before the service reports ready; other descriptors are built on their first query.

Example:
    atr service template_store --set recognition.descriptor=fpfh --cache templates/
    atr service template_store --set "pipeline.target_meshes=[my_tank.ply]"

"""

from __future__ import annotations

from pathlib import Path

from atr.template_store import TemplateStore
from bus.launcher import REPO
from bus.service import effective_config, service_arguments, start_node


def main(argv: list[str] | None = None) -> int:
    """Run the service until stopped."""
    parser = service_arguments("template_store", __doc__)
    parser.add_argument(
        "--cache", type=Path, default=REPO / "templates", help="template cache folder"
    )
    args = parser.parse_args(argv)
    config = effective_config(args)
    with start_node("template_store", args, inputs=[]) as node:
        store = TemplateStore(config, args.cache)
        for target in store.meshes:
            store.message(target, config.recognition.descriptor)

        def answer(key: str) -> dict | None:
            _, _, target, descriptor = key.split("/")
            return store.message(target, descriptor)

        node.serve("atr/templates/*/*", answer)
        node.ready()
        for _ in node.events():
            pass
    return 0
