"""spslam.Extractor against `spslam extract --json` on the same image."""

import json

import numpy as np
import pytest

import spslam
from conftest import gray, run_cli


@pytest.fixture(scope="module")
def frame(kitti06):
    return kitti06 / "image_0" / "000000.png"


@pytest.fixture(scope="module")
def extractor():
    return spslam.Extractor(1000)


def test_extraction_equals_the_cli(frame, extractor, spslam_bin, tmp_path):
    out = tmp_path / "features.json"
    run_cli(spslam_bin, "extract", frame, "--features", "1000", "--json", out)
    cli = json.loads(out.read_text())
    features = extractor.extract(gray(frame))
    assert len(features) == len(cli["keypoints"]) == 1000
    keypoints = cli["keypoints"]
    columns = {
        "x": features.keypoints[:, 0],
        "y": features.keypoints[:, 1],
        "response": features.scores,
        "angle": features.angles,
        "size": features.sizes,
        "octave": features.octaves,
    }
    for name, column in columns.items():
        expected = np.array([k[name] for k in keypoints], dtype=column.dtype)
        np.testing.assert_array_equal(column, expected, err_msg=name)
    expected = np.array(cli["descriptors"], dtype=np.float32)
    assert features.descriptors.shape == (1000, cli["descriptor_len"]) == (1000, 256)
    np.testing.assert_array_equal(features.descriptors, expected)


def test_descriptors_are_unit_rows_and_binary_is_their_sign(frame, extractor):
    features = extractor.extract(gray(frame))
    d = features.descriptors
    assert d.dtype == np.float32
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-4)
    bits = np.packbits(d > 0, axis=1, bitorder="little")
    np.testing.assert_array_equal(features.binary_descriptors, bits)
    assert features.binary_descriptors.shape == (len(features), 32)


def test_colour_input_is_converted_like_opencv(frame, extractor):
    image = gray(frame)
    reference = extractor.extract(image)
    # Equal channels convert back to the same gray values, in either order.
    for colour in (np.dstack([image] * 3), np.dstack([image] * 3 + [np.full_like(image, 255)])):
        same = extractor.extract(colour)
        np.testing.assert_array_equal(same.keypoints, reference.keypoints)
        np.testing.assert_array_equal(same.descriptors, reference.descriptors)
    # An RGB image with rgb=True equals its BGR twin read as BGR.
    rng = np.random.default_rng(7)
    tint = rng.integers(0, 40, size=3, dtype=np.uint8)
    bgr = np.clip(np.dstack([image] * 3).astype(np.int16) - tint, 0, 255).astype(np.uint8)
    from_bgr = extractor.extract(bgr)
    from_rgb = extractor.extract(np.ascontiguousarray(bgr[:, :, ::-1]), rgb=True)
    np.testing.assert_array_equal(from_bgr.descriptors, from_rgb.descriptors)


def test_non_contiguous_input_equals_a_copy(frame, extractor):
    image = gray(frame)
    strided = np.zeros((image.shape[0], image.shape[1] * 2), dtype=np.uint8)
    strided[:, ::2] = image
    view = strided[:, ::2]
    assert not view.flags["C_CONTIGUOUS"]
    np.testing.assert_array_equal(
        extractor.extract(view).descriptors, extractor.extract(image).descriptors
    )


def test_named_models_and_settings():
    lite = spslam.Extractor(500, model="lite", anms="ssc", precision="fp32")
    assert lite.model_path.name == "superpoint_lite.onnx"
    assert lite.descriptor_len == 256
    image = np.random.default_rng(1).integers(0, 255, (240, 320), dtype=np.uint8)
    features = lite.extract(image)
    assert 0 < len(features) <= 500
    assert set(features.timings) >= {"inference", "total"}
