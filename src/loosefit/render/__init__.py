"""Offscreen rendering of body + garment animations, and video / image writers.

* ``camera.py``   -- pure view / projection matrices, named views, framing and follow tracks.
* ``geometry.py`` -- smooth vertex normals and the primitive meshes used by tests and benchmarks.
* ``shaders.py``  -- the GLSL sources (shadow pass, lit meshes, floor).
* ``renderer.py`` -- ``RenderConfig``, ``RenderMesh`` and the moderngl ``Renderer`` (EGL, headless).
* ``video.py``    -- atomic MP4 / PNG writers and ``contact_sheet``.

Quickstart::

    from loosefit.render.renderer import Renderer, RenderConfig, RenderMesh
    from loosefit.render.video import write_video

    scene = [RenderMesh(body_faces, body_verts, role="body"), RenderMesh(skirt_faces, skirt_verts)]
    with Renderer(RenderConfig(views=("front", "side"))) as r:
        write_video(r.render_sequence(scene, title="clip 01"), "clip.mp4", fps=30)
"""
