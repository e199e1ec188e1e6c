//! The few quaternion operations placing a character needs (w x y z, MuJoCo's order).

/// Hamilton product `a ⊗ b`.
pub fn mul(a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
    [
        a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
        a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
        a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
        a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0],
    ]
}

/// Rotation by `yaw` radians about +z.
pub fn yaw_quat(yaw: f64) -> [f64; 4] {
    let (s, c) = (0.5 * yaw).sin_cos();
    [c, 0.0, 0.0, s]
}

/// Heading of an orientation: the angle of its +x axis projected on the floor.
pub fn yaw_of(q: [f64; 4]) -> f64 {
    let [w, x, y, z] = q;
    // First column of the rotation matrix: (1 − 2(y² + z²), 2(xy + wz), ...).
    (2.0 * (x * y + w * z)).atan2(1.0 - 2.0 * (y * y + z * z))
}

/// `v` rotated by `yaw` about +z.
pub fn rotate_z(yaw: f64, v: [f64; 3]) -> [f64; 3] {
    let (s, c) = yaw.sin_cos();
    [c * v[0] - s * v[1], s * v[0] + c * v[1], v[2]]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn yaw_round_trips_through_quaternions() {
        for yaw in [-3.0, -1.2, 0.0, 0.7, 2.9] {
            assert!((yaw_of(yaw_quat(yaw)) - yaw).abs() < 1e-12);
            let q = mul(yaw_quat(yaw), yaw_quat(0.3));
            assert!((yaw_of(q) - repertoire_scenes::math::wrap_angle(yaw + 0.3)).abs() < 1e-12);
        }
        let v = rotate_z(std::f64::consts::FRAC_PI_2, [1.0, 0.0, 0.5]);
        assert!((v[0]).abs() < 1e-12 && (v[1] - 1.0).abs() < 1e-12 && v[2] == 0.5);
    }
}
