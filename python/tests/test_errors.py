"""Bad input raises a Python exception that says what to fix; nothing panics."""

import numpy as np
import pytest

import spslam


@pytest.fixture(scope="module")
def extractor():
    return spslam.Extractor(200)


def test_image_type_and_shape(extractor):
    image = np.zeros((120, 160), dtype=np.uint8)
    with pytest.raises(TypeError, match="uint8.*float64"):
        extractor.extract(image.astype(np.float64))
    with pytest.raises(TypeError, match="uint8"):
        extractor.extract([[0, 1], [2, 3]])
    with pytest.raises(ValueError, match="shape"):
        extractor.extract(np.zeros((4, 120, 160), dtype=np.uint8))
    with pytest.raises(ValueError, match="shape"):
        extractor.extract(np.zeros((120, 160, 2), dtype=np.uint8))
    with pytest.raises(ValueError, match="shape"):
        extractor.extract(np.zeros(160, dtype=np.uint8))
    with pytest.raises(ValueError):
        extractor.extract(np.zeros((0, 160), dtype=np.uint8))
    with pytest.raises(ValueError, match="at least 16 px"):
        extractor.extract(np.zeros((8, 8), dtype=np.uint8))


def test_settings_and_models(tmp_path):
    with pytest.raises(FileNotFoundError, match="missing.onnx"):
        spslam.Extractor(model=str(tmp_path / "missing.onnx"))
    with pytest.raises(ValueError, match="anms"):
        spslam.Extractor(anms="bogus")
    with pytest.raises(ValueError, match="precision"):
        spslam.Extractor(precision="int4")
    with pytest.raises(ValueError):
        spslam.Extractor(0)
    with pytest.raises(OverflowError):
        spslam.Extractor(-5)


def test_a_flat_image_gives_no_features_not_an_error(extractor):
    features = extractor.extract(np.full((120, 160), 128, dtype=np.uint8))
    assert len(features) == 0
    assert features.descriptors.shape == (0, 256)
    assert features.binary_descriptors.shape == (0, 32)
