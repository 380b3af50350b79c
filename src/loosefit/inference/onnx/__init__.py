"""The pipeline as ONNX graphs: exported (:mod:`.export`), run in onnxruntime
(:mod:`.runtime`), and the learned stages as graphs the rollout calls (:mod:`.stages`)."""
