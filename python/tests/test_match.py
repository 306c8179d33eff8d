"""spslam.match against a brute-force NumPy reference of the same rule:
Lowe's ratio (strict: best < ratio × second), the distance bound, and the
mutual check (the train row's nearest query, first on ties)."""

import numpy as np
import pytest

import spslam
from conftest import gray


def reference_match(q, t, distance, ratio, mutual, max_distance=np.inf):
    d = distance(q, t)
    pairs = []
    for i in range(len(q)):
        order = np.argsort(d[i], kind="stable")
        best = order[0]
        if d[i, best] > max_distance:
            continue
        if ratio is not None and len(order) > 1 and not d[i, best] < ratio * d[i, order[1]]:
            continue
        if mutual and int(np.argmin(d[:, best])) != i:
            continue
        pairs.append((i, best, d[i, best]))
    return pairs


def l2(q, t):
    q64, t64 = q.astype(np.float64), t.astype(np.float64)
    return np.sqrt(np.maximum(((q64[:, None, :] - t64[None, :, :]) ** 2).sum(-1), 0))


def hamming(q, t):
    x = np.bitwise_xor(q[:, None, :], t[None, :, :])
    return np.unpackbits(x, axis=2).sum(-1).astype(np.float64)


@pytest.fixture(scope="module")
def stereo_features(kitti06):
    extractor = spslam.Extractor(500)
    left = extractor.extract(gray(kitti06 / "image_0" / "000000.png"))
    right = extractor.extract(gray(kitti06 / "image_1" / "000000.png"))
    return left, right


@pytest.mark.parametrize("ratio,mutual", [(0.7, True), (0.8, False), (None, True)])
def test_float_matching_equals_brute_force(stereo_features, ratio, mutual):
    left, right = stereo_features
    pairs, distances = spslam.match(left.descriptors, right.descriptors, ratio=ratio, mutual=mutual)
    expected = reference_match(left.descriptors, right.descriptors, l2, ratio, mutual)
    assert pairs.dtype == np.int64 and pairs.shape == (len(expected), 2)
    assert len(expected) > 100
    np.testing.assert_array_equal(pairs, np.array([(i, j) for i, j, _ in expected]))
    np.testing.assert_allclose(distances, [d for _, _, d in expected], atol=1e-5)


def test_distance_bound(stereo_features):
    left, right = stereo_features
    pairs, distances = spslam.match(
        left.descriptors, right.descriptors, ratio=None, mutual=False, max_distance=0.8
    )
    expected = reference_match(left.descriptors, right.descriptors, l2, None, False, 0.8)
    np.testing.assert_array_equal(pairs, np.array([(i, j) for i, j, _ in expected]))
    assert distances.max() <= 0.8


def test_binary_matching_is_hamming(stereo_features):
    left, right = stereo_features
    pairs, distances = spslam.match(
        left.binary_descriptors, right.binary_descriptors, ratio=0.8, mutual=True
    )
    expected = reference_match(
        left.binary_descriptors, right.binary_descriptors, hamming, 0.8, True
    )
    np.testing.assert_array_equal(pairs, np.array([(i, j) for i, j, _ in expected]))
    np.testing.assert_array_equal(distances, np.array([d for _, _, d in expected], np.float32))


def test_kinds_must_agree(stereo_features):
    left, right = stereo_features
    with pytest.raises(ValueError, match="cannot compare"):
        spslam.match(left.descriptors, right.binary_descriptors)
    with pytest.raises(ValueError, match="32 bytes"):
        spslam.match(left.binary_descriptors[:, :16], right.binary_descriptors[:, :16])
    with pytest.raises(TypeError, match="float32"):
        spslam.match(left.descriptors.astype(np.float64), right.descriptors)
    with pytest.raises(ValueError, match="ratio"):
        spslam.match(left.descriptors, right.descriptors, ratio=-1.0)
