"""The render pipeline: from a validated IR scene to a :class:`~blendify_core.pipeline.result.RenderResult`.

``bf.render`` (:mod:`.render`) resolves settings (:mod:`.settings`), analyses effects (:mod:`.effects`),
checks capabilities (:mod:`.capabilities`), re-centres far scenes (:mod:`.recentre`), handles lens
distortion (:mod:`.distortion`) and calls a backend (:mod:`.backend`, whose translators share one shape,
:mod:`.translator`).
"""
