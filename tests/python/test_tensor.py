# streetlight.Tensor: numpy round trips through the buffer protocol, and a forward and backward
# of a few ops checked against their derivatives by hand.
import numpy as np
import pytest

import streetlight as sl


@pytest.mark.parametrize("dtype", [np.float32, np.float64, np.int64])
def test_tensor_round_trips_numpy_unchanged(dtype):
    a = (np.arange(24).reshape(2, 3, 4) * 1.25 - 7).astype(dtype)
    t = sl.Tensor(a)
    assert t.shape == (2, 3, 4)
    back = np.asarray(t)
    assert back.dtype == a.dtype
    assert np.array_equal(back, a)
    assert back.tobytes() == a.tobytes()


def test_numpy_view_shares_the_tensors_memory():
    t = sl.Tensor(np.zeros((3, 2), np.float32))
    v = t.numpy()
    w = np.asarray(t)
    v[1, 1] = 5.0
    assert w[1, 1] == 5.0
    assert np.asarray(t)[1, 1] == 5.0
    del t  # the views keep the storage alive
    assert v.sum() == 5.0


def test_transposed_view_keeps_its_strides_without_a_copy():
    a = np.arange(6, dtype=np.float64).reshape(2, 3)
    t = sl.Tensor(a).transpose(0, 1)
    v = np.asarray(t)
    assert v.shape == (3, 2)
    assert not v.flags["C_CONTIGUOUS"]
    assert np.array_equal(v, a.T)


def test_tensor_of_unsupported_dtype_is_a_value_error():
    with pytest.raises(ValueError, match="float32, float64 or int64.*uint8"):
        sl.Tensor(np.zeros((2, 2), np.uint8))


def test_forward_and_backward_match_the_derivatives_by_hand():
    x0 = np.array([0.3, -1.2, 2.0], np.float64)
    w0 = np.array([[0.5], [-0.25], [1.5]], np.float64)
    x = sl.Tensor(x0.reshape(1, 3), requires_grad=True)
    w = sl.Tensor(w0, requires_grad=True)
    # y = sum(tanh(x @ w) ** 2 + exp(x) * 3)
    y = ((x @ w).tanh() ** 2).sum() + (x.exp() * 3.0).sum()
    z = float(np.tanh(x0 @ w0)[0])
    assert y.item() == pytest.approx(z * z + 3 * np.exp(x0).sum(), rel=1e-12)
    y.backward()
    dz = 2 * z * (1 - z * z)
    assert np.allclose(x.grad.numpy().ravel(), dz * w0.ravel() + 3 * np.exp(x0), rtol=1e-12)
    assert np.allclose(w.grad.numpy().ravel(), dz * x0, rtol=1e-12)


def test_gradient_matches_a_finite_difference():
    x0 = np.array([0.2, 0.7, -0.4], np.float64)

    def f(v):
        t = sl.Tensor(v, requires_grad=True)
        y = (t.sigmoid() * t.sin() + t.square()).mean()
        return y, t

    y, t = f(x0)
    y.backward()
    eps = 1e-6
    for i in range(3):
        d = np.zeros(3)
        d[i] = eps
        fd = (f(x0 + d)[0].item() - f(x0 - d)[0].item()) / (2 * eps)
        assert t.grad.numpy()[i] == pytest.approx(fd, rel=1e-6)
