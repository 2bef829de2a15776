"""The ONNX stereo harness, with tiny stereo networks built here with onnx.helper."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

onnx = pytest.importorskip("onnx")

from benchmarks.methods import Setup  # noqa: E402
from benchmarks.stereo_onnx import OnnxStereo, OnnxStereoError, onnx_method, parse_options  # noqa: E402

from onnx import TensorProto, helper  # noqa: E402

from tests.helpers.onnx_stereo import OPSET, build_constant, build_sad_wta, textured_pair  # noqa: E402


@pytest.fixture(scope="module")
def sad_model(tmp_path_factory) -> Path:
    return build_sad_wta(tmp_path_factory.mktemp("onnx") / "sad_wta.onnx", 8)


def test_sad_network_recovers_known_disparity(sad_model):
    left, right = textured_pair(5)
    stereo = OnnxStereo(sad_model)
    disp = stereo.compute(left, right)
    assert disp.dtype == np.float32 and disp.shape == left.shape[:2]
    interior = disp[2:-2, 10:-2]
    np.testing.assert_array_equal(interior, np.float32(5.0))


@pytest.mark.parametrize("shift", [0, 3, 7])
def test_sad_network_each_shift_and_grey_input(sad_model, shift):
    left, right = textured_pair(shift, seed=shift)
    disp = OnnxStereo(sad_model, pad_multiple=8).compute(left[:, :, 0], right[:, :, 0])
    np.testing.assert_array_equal(disp[2:-2, 10:-2], np.float32(shift))


def test_metadata_gives_size_and_scale_and_output_is_rescaled(tmp_path):
    path = build_constant(tmp_path / "c.onnx", 3.0, width=48, height=32, metadata={"output_scale": "2", "mean": "0.5", "std": "0.25"})
    stereo = OnnxStereo(path)
    assert stereo.config.input_size == (48, 32)
    assert stereo.config.output_scale == 2.0 and stereo.config.mean == (0.5,) and stereo.config.std == (0.25,)
    left = np.zeros((64, 96, 3), np.uint8)
    disp = stereo.compute(left, left)
    # 3 (raw) x 2 (output_scale) at 48 px wide, times 96 / 48 back in the image's pixels
    assert disp.shape == (64, 96)
    np.testing.assert_allclose(disp, 12.0)


def test_options_override_metadata_and_min_disparity_gives_nan(tmp_path):
    path = build_constant(tmp_path / "c.onnx", 3.0, width=48, height=32, metadata={"output_scale": "2"})
    disp = OnnxStereo(path, output_scale=-1.0).compute(np.zeros((32, 48, 3), np.uint8), np.zeros((32, 48, 3), np.uint8))
    assert np.isnan(disp).all()   # -3 < min_disparity 0: unknown, never a negative disparity


def test_onnx_method_runs_as_a_benchmark_method(sad_model):
    method = onnx_method(sad_model)
    assert method.name == "onnx:sad_wta" and method.family == "onnx" and method.available
    left, right = textured_pair(4)
    disp = method.prepare(Setup(num_disparities=16, threads=1))(left, right)
    np.testing.assert_array_equal(disp[2:-2, 10:-2], np.float32(4.0))


def test_missing_file(tmp_path):
    with pytest.raises(FileNotFoundError, match="model"):
        OnnxStereo(tmp_path / "nope.onnx")


def test_not_onnx(tmp_path):
    bad = tmp_path / "bad.onnx"
    bad.write_bytes(b"this is not a protobuf\x00\xff" * 10)
    with pytest.raises(OnnxStereoError, match="could not be loaded"):
        OnnxStereo(bad)


def test_one_input_model_is_refused(tmp_path):
    graph = helper.make_graph([helper.make_node("Identity", ["left"], ["disparity"])], "one",
                              [helper.make_tensor_value_info("left", TensorProto.FLOAT, [1, 3, 8, 8])],
                              [helper.make_tensor_value_info("disparity", TensorProto.FLOAT, [1, 3, 8, 8])])
    path = tmp_path / "one.onnx"
    onnx.save(helper.make_model(graph, opset_imports=OPSET, ir_version=8), str(path))
    with pytest.raises(OnnxStereoError, match="two image inputs"):
        OnnxStereo(path)


def test_colour_channels_mismatch_is_refused(tmp_path):
    path = build_constant(tmp_path / "c.onnx", 1.0, width=16, height=16)
    with pytest.raises(OnnxStereoError, match="channels"):
        OnnxStereo(path, color="gray")


@pytest.mark.parametrize(
    ("options", "word"),
    [({"input_size": "640by480"}, "input_size"), ({"mean": "a,b"}, "mean"), ({"output_scale": "x"}, "output_scale"),
     ({"pad_multiple": "z"}, "pad_multiple")],
)
def test_bad_option_strings(options, word):
    with pytest.raises(OnnxStereoError, match=word):
        parse_options(options)


@pytest.mark.parametrize(("field", "value"), [("color", "cmyk"), ("std", (0.0,)), ("output_scale", float("nan")), ("pad_multiple", 0)])
def test_bad_option_values(sad_model, field, value):
    with pytest.raises(OnnxStereoError, match=field):
        OnnxStereo(sad_model, **{field: value})


def test_bad_images(sad_model):
    stereo = OnnxStereo(sad_model)
    with pytest.raises(ValueError, match="same shape"):
        stereo.compute(np.zeros((8, 8, 3), np.uint8), np.zeros((8, 9, 3), np.uint8))
    with pytest.raises(ValueError, match="uint8"):
        stereo.compute(np.zeros((8, 8, 3), np.float32), np.zeros((8, 8, 3), np.float32))


from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402


@settings(max_examples=120, deadline=None)
@given(h=st.integers(1, 24), w=st.integers(1, 40), grey=st.booleans(), dtype=st.sampled_from([np.uint8, np.uint16, np.float32]),
       seed=st.integers(0, 2**16))
def test_property_any_image_gives_a_map_or_a_clear_error(sad_model, h, w, grey, dtype, seed):
    rng = np.random.default_rng(seed)
    shape = (h, w) if grey else (h, w, 3)
    left = rng.integers(0, 255, shape).astype(dtype)
    right = rng.integers(0, 255, shape).astype(dtype)
    stereo = OnnxStereo(sad_model)
    if dtype is not np.uint8:
        with pytest.raises(ValueError, match="uint8"):
            stereo.compute(left, right)
        return
    disp = stereo.compute(left, right)
    assert disp.shape == (h, w) and disp.dtype == np.float32
    finite = disp[np.isfinite(disp)]
    assert ((finite >= 0) & (finite < 8)).all()
