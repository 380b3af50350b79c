"""The engine tier at run time: the checkpoint and its rollout in PyTorch (:mod:`.model`),
its one-graph-a-frame ONNX export with capsules (:mod:`.export`) and that graph run in
onnxruntime (:mod:`.runtime`). Its network is :mod:`loosefit.model.engine`; its training
:mod:`loosefit.train.engine`."""
