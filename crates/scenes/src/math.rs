//! Small rigid-body helpers: frames, headings and angles.

use std::f64::consts::PI;

/// A position and a row-major 3×3 rotation matrix (MuJoCo's `xmat` layout).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame {
    /// Origin in world coordinates.
    pub pos: [f64; 3],
    /// Rotation, row-major; column k is the frame's k-th axis in world coordinates.
    pub rot: [f64; 9],
}

impl Frame {
    /// Heading: the angle of the frame's +x axis projected on the floor, from world +x.
    pub fn yaw(&self) -> f64 {
        self.rot[3].atan2(self.rot[0])
    }

    /// Pitch (Z-Y-X Euler): positive when +x tips down.
    pub fn pitch(&self) -> f64 {
        (-self.rot[6]).clamp(-1.0, 1.0).asin()
    }

    /// Roll (Z-Y-X Euler): positive when +y tips up.
    pub fn roll(&self) -> f64 {
        self.rot[7].atan2(self.rot[8])
    }
}

/// The product `a · b` of two quaternions (w, x, y, z): `b`'s rotation, then `a`'s.
pub fn quat_mul(a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
    [
        a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
        a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
        a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
        a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0],
    ]
}

/// Wraps an angle into (−π, π].
pub fn wrap_angle(a: f64) -> f64 {
    let mut a = (a + PI).rem_euclid(2.0 * PI) - PI;
    if a <= -PI {
        a += 2.0 * PI;
    }
    a
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wraps_angles() {
        assert!((wrap_angle(3.0 * PI / 2.0) + PI / 2.0).abs() < 1e-12);
        assert!((wrap_angle(-PI) - PI).abs() < 1e-12);
        assert!((wrap_angle(0.3) - 0.3).abs() < 1e-12);
    }

    #[test]
    fn euler_angles_of_a_yawed_pitched_frame() {
        // R = Rz(yaw) * Ry(pitch)
        let (y, p) = (0.7f64, 0.2f64);
        let (sy, cy, sp, cp) = (y.sin(), y.cos(), p.sin(), p.cos());
        let rot = [cy * cp, -sy, cy * sp, sy * cp, cy, sy * sp, -sp, 0.0, cp];
        let f = Frame { pos: [0.0; 3], rot };
        assert!((f.yaw() - y).abs() < 1e-12);
        assert!((f.pitch() - p).abs() < 1e-12);
        assert!(f.roll().abs() < 1e-12);
    }
}
