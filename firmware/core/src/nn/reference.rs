//! The f32 reference of the layers, for host-side comparisons with the fixed-point path.

/// `y = W x + b` with `W` row-major `[y.len(), x.len()]`; uses the overlapping sizes.
pub fn dense_f32(weight: &[f32], bias: &[f32], x: &[f32], y: &mut [f32]) {
    let n = x.len();
    for ((out, row), b) in y.iter_mut().zip(weight.chunks_exact(n.max(1))).zip(bias) {
        *out = row.iter().zip(x).map(|(w, x)| w * x).sum::<f32>() + b;
    }
}

/// ELU (alpha 1).
pub fn elu_f32(x: f32) -> f32 {
    if x > 0.0 {
        x
    } else {
        libm::expm1f(x)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dense_is_row_major() {
        let mut y = [0.0; 2];
        dense_f32(&[1.0, 2.0, 3.0, 4.0], &[0.5, -0.5], &[1.0, 1.0], &mut y);
        assert_eq!(y, [3.5, 6.5]);
        assert_eq!(elu_f32(2.0), 2.0);
        assert!((elu_f32(-1.0) + 0.632_120_5).abs() < 1e-6);
    }
}
