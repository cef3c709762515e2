"""Ground-truth records: the JSONL form keeps its keys, order and numbers; records read back equal."""

from __future__ import annotations

import json

import pytest

from harness.world.truth import CameraTruth, EgoTruth, FrameTruth, ObjectTruth

#: One ``ground_truth.jsonl`` line as the renderer writes it (moving camera: with the ``camera`` block).
LINE = ('{"frame":3,"t":0.2,"ego":{"speed":25.0,"x":105.0,"y":4.0,"heading":0.0,"lane":1,"crashed":false},'
        '"objects":[{"id":2,"name":"car","box":[301.5,170.5,340.5,201.5],"visibility":0.8125,"d_long":19.1,'
        '"d_lat":-0.35,"v_long":-3.0000000000000004,"v_lat":0.0,"ttc":null,"lane_rel":0,'
        '"corners_cam":[[-1.25,1.3,19.1],[0.75,1.3,19.1],[0.75,1.3,24.1],[-1.25,1.3,24.1],'
        '[-1.25,-0.2,19.1],[0.75,-0.2,19.1],[0.75,-0.2,24.1],[-1.25,-0.2,24.1]],'
        '"length":5.0,"width":2.0,"crashed":false}],'
        '"camera":{"pitch_rad":0.021,"roll_rad":-0.004,"horizon_row":187.25,"pitch_offset_rad":0.001,'
        '"horizon_offset_px":0.5}}')


def test_jsonl_line_round_trips_byte_for_byte():
    rec = FrameTruth.from_json(json.loads(LINE))
    assert json.dumps(rec.to_json(), separators=(",", ":")) == LINE
    assert FrameTruth.from_json(json.loads(json.dumps(rec.to_json()))) == rec
    (obj,) = rec.objects
    assert obj.box == (301.5, 170.5, 340.5, 201.5) and obj.ttc is None and obj.counted is None
    assert rec.ego.speed == 25.0 and rec.camera == CameraTruth(0.021, -0.004, 187.25, 0.001, 0.5)


def test_optional_blocks_and_fields():
    ego = EgoTruth(speed=10.0)
    bare = FrameTruth(frame=0, t=0.0, ego=ego)
    assert "camera" not in bare.to_json() and bare.to_json()["objects"] == [] and bare.min_ttc is None
    labelled = ObjectTruth(id=1, box=(0, 0, 4, 4), visibility=1.0, d_long=9.0, d_lat=0.0, v_long=None, v_lat=None,
                           ttc=2.5, counted=False)
    d = labelled.to_json()
    assert list(d)[-1] == "counted" and d["counted"] is False          # only a labelled dataset writes it
    assert ObjectTruth.from_json(d) == labelled
    two = FrameTruth(frame=0, t=0.0, ego=ego, objects=(labelled, ObjectTruth.from_json({**d, "ttc": 1.5})))
    assert two.min_ttc == 1.5


def test_records_are_frozen():
    rec = FrameTruth.from_json(json.loads(LINE))
    with pytest.raises(AttributeError):
        rec.objects[0].d_long = 1.0
