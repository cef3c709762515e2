"""Training pipeline of the project's CenterNet vehicle detector (scripts; not installed).

``python -m training.reproduce`` renders the data with the harness, trains (CPU,
torch from the ``train`` extra), exports ``monorarp/models/centernet_vehicle.onnx``
and writes its metadata + validation figures to ``centernet_vehicle.json``.
"""
