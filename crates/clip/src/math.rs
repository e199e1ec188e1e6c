//! Small maths for clips: quaternions in MuJoCo's `w x y z` order, slerp, headings, and a
//! Cholesky solve for the IK normal equations.

use std::f64::consts::PI;
use std::ops::Mul;

/// A unit quaternion `w x y z` (MuJoCo's order); `a * b` applies `b` first.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Q {
    /// Scalar part.
    pub w: f64,
    /// i.
    pub x: f64,
    /// j.
    pub y: f64,
    /// k.
    pub z: f64,
}

impl Q {
    /// The identity.
    pub const IDENTITY: Q = Q { w: 1.0, x: 0.0, y: 0.0, z: 0.0 };

    /// From the first four values of a qpos slice (`w x y z`); missing values read as identity.
    pub fn from_slice(s: &[f64]) -> Q {
        match s {
            [w, x, y, z, ..] => Q { w: *w, x: *x, y: *y, z: *z },
            _ => Q::IDENTITY,
        }
    }

    /// `[w, x, y, z]`.
    pub fn to_array(self) -> [f64; 4] {
        [self.w, self.x, self.y, self.z]
    }

    /// Rotation by `angle` radians about a unit axis.
    pub fn axis_angle(axis: [f64; 3], angle: f64) -> Q {
        let (s, c) = (0.5 * angle).sin_cos();
        Q { w: c, x: axis[0] * s, y: axis[1] * s, z: axis[2] * s }
    }

    /// The inverse of a unit quaternion.
    pub fn conj(self) -> Q {
        Q { w: self.w, x: -self.x, y: -self.y, z: -self.z }
    }

    /// 4-D dot product.
    pub fn dot(self, o: Q) -> f64 {
        self.w * o.w + self.x * o.x + self.y * o.y + self.z * o.z
    }

    /// Scaled to unit length (identity when degenerate).
    pub fn normalized(self) -> Q {
        let n = self.dot(self).sqrt();
        if n > 1e-12 && n.is_finite() {
            Q { w: self.w / n, x: self.x / n, y: self.y / n, z: self.z / n }
        } else {
            Q::IDENTITY
        }
    }

    /// Rotates a vector.
    pub fn rotate(self, v: [f64; 3]) -> [f64; 3] {
        let u = [self.x, self.y, self.z];
        let t = cross(u, v).map(|c| 2.0 * c);
        let ut = cross(u, t);
        [v[0] + self.w * t[0] + ut[0], v[1] + self.w * t[1] + ut[1], v[2] + self.w * t[2] + ut[2]]
    }
}

impl Mul for Q {
    type Output = Q;
    fn mul(self, o: Q) -> Q {
        Q {
            w: self.w * o.w - self.x * o.x - self.y * o.y - self.z * o.z,
            x: self.w * o.x + self.x * o.w + self.y * o.z - self.z * o.y,
            y: self.w * o.y - self.x * o.z + self.y * o.w + self.z * o.x,
            z: self.w * o.z + self.x * o.y - self.y * o.x + self.z * o.w,
        }
    }
}

/// Cross product.
pub fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

/// `a - b`.
pub fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// Euclidean length.
pub fn norm(a: [f64; 3]) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

/// Spherical interpolation from `a` (u = 0) to `b` (u = 1) along the shorter arc.
pub fn slerp(a: Q, b: Q, u: f64) -> Q {
    let mut d = a.dot(b);
    let b = if d < 0.0 {
        d = -d;
        Q { w: -b.w, x: -b.x, y: -b.y, z: -b.z }
    } else {
        b
    };
    let (ka, kb) = if d > 0.9995 {
        (1.0 - u, u)
    } else {
        let th = d.clamp(-1.0, 1.0).acos();
        let s = th.sin();
        (((1.0 - u) * th).sin() / s, (u * th).sin() / s)
    };
    Q { w: ka * a.w + kb * b.w, x: ka * a.x + kb * b.x, y: ka * a.y + kb * b.y, z: ka * a.z + kb * b.z }.normalized()
}

/// Rotation by `yaw` radians about +z.
pub fn yaw_quat(yaw: f64) -> Q {
    Q::axis_angle([0.0, 0.0, 1.0], yaw)
}

/// Heading of a z-up orientation: the angle of its +x axis on the floor (counter-clockwise).
pub fn heading_of_quat(q: Q) -> f64 {
    let f = q.rotate([1.0, 0.0, 0.0]);
    f[1].atan2(f[0])
}

/// Removes 2π jumps from a sequence of angles in place.
pub fn unwrap_angles(a: &mut [f64]) {
    for i in 1..a.len() {
        let d = a[i] - a[i - 1];
        a[i] -= 2.0 * PI * (d / (2.0 * PI)).round();
    }
}

/// Solves `H x = g` in place for a symmetric positive-definite `n × n` H (row-major),
/// overwriting `h` with its Cholesky factor and `g` with `x`. Returns false if H is not
/// positive definite.
pub fn cholesky_solve(h: &mut [f64], g: &mut [f64], n: usize) -> bool {
    for j in 0..n {
        let mut d = h[j * n + j];
        for k in 0..j {
            d -= h[j * n + k] * h[j * n + k];
        }
        if d.is_nan() || d <= 0.0 {
            return false;
        }
        let d = d.sqrt();
        h[j * n + j] = d;
        for i in j + 1..n {
            let mut s = h[i * n + j];
            for k in 0..j {
                s -= h[i * n + k] * h[j * n + k];
            }
            h[i * n + j] = s / d;
        }
    }
    for i in 0..n {
        let mut s = g[i];
        for k in 0..i {
            s -= h[i * n + k] * g[k];
        }
        g[i] = s / h[i * n + i];
    }
    for i in (0..n).rev() {
        let mut s = g[i];
        for k in i + 1..n {
            s -= h[k * n + i] * g[k];
        }
        g[i] = s / h[i * n + i];
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cholesky_solves_a_small_system() {
        let mut h = vec![4.0, 2.0, 2.0, 3.0];
        let mut g = vec![2.0, 1.0];
        assert!(cholesky_solve(&mut h, &mut g, 2));
        assert!((4.0 * g[0] + 2.0 * g[1] - 2.0).abs() < 1e-12);
        assert!((2.0 * g[0] + 3.0 * g[1] - 1.0).abs() < 1e-12);
        let mut bad = vec![0.0, 0.0, 0.0, 0.0];
        assert!(!cholesky_solve(&mut bad, &mut [1.0, 1.0], 2));
    }

    #[test]
    fn slerp_halfway_and_heading() {
        let a = yaw_quat(0.0);
        let b = yaw_quat(1.0);
        assert!((heading_of_quat(slerp(a, b, 0.5)) - 0.5).abs() < 1e-12);
        let mut h = vec![3.0, -3.0, -2.9];
        unwrap_angles(&mut h);
        assert!((h[1] - (2.0 * PI - 3.0)).abs() < 1e-12 && h[2] > h[1]);
    }
}
