//! Small 3-D rotation maths: vectors, unit quaternions and Euler angles in any axis order.
//!
//! Conventions: column vectors, right-handed axes, positive angles rotate counter-clockwise
//! when looking down the axis towards the origin. A quaternion `q` rotates a vector `v` as
//! `q v q*`; `a * b` applies `b` first, then `a` (the same as the matrix product `A B`).

use std::f64::consts::PI;
use std::ops::{Add, AddAssign, Mul, Neg, Sub};

/// A 3-D vector (positions in metres unless a function says otherwise).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Vec3 {
    /// x component.
    pub x: f64,
    /// y component.
    pub y: f64,
    /// z component.
    pub z: f64,
}

impl Vec3 {
    /// The zero vector.
    pub const ZERO: Vec3 = Vec3::new(0.0, 0.0, 0.0);

    /// Builds a vector from its components.
    pub const fn new(x: f64, y: f64, z: f64) -> Self {
        Vec3 { x, y, z }
    }

    /// The component along `axis`.
    pub fn get(self, axis: Axis) -> f64 {
        match axis {
            Axis::X => self.x,
            Axis::Y => self.y,
            Axis::Z => self.z,
        }
    }

    /// Sets the component along `axis`.
    pub fn set(&mut self, axis: Axis, value: f64) {
        match axis {
            Axis::X => self.x = value,
            Axis::Y => self.y = value,
            Axis::Z => self.z = value,
        }
    }

    /// Dot product.
    pub fn dot(self, o: Vec3) -> f64 {
        self.x * o.x + self.y * o.y + self.z * o.z
    }

    /// Cross product.
    pub fn cross(self, o: Vec3) -> Vec3 {
        Vec3::new(self.y * o.z - self.z * o.y, self.z * o.x - self.x * o.z, self.x * o.y - self.y * o.x)
    }

    /// Euclidean length.
    pub fn norm(self) -> f64 {
        self.dot(self).sqrt()
    }

    /// True when every component is finite.
    pub fn is_finite(self) -> bool {
        self.x.is_finite() && self.y.is_finite() && self.z.is_finite()
    }

    /// The components as an array.
    pub fn to_array(self) -> [f64; 3] {
        [self.x, self.y, self.z]
    }
}

impl Add for Vec3 {
    type Output = Vec3;
    fn add(self, o: Vec3) -> Vec3 {
        Vec3::new(self.x + o.x, self.y + o.y, self.z + o.z)
    }
}

impl AddAssign for Vec3 {
    fn add_assign(&mut self, o: Vec3) {
        *self = *self + o;
    }
}

impl Sub for Vec3 {
    type Output = Vec3;
    fn sub(self, o: Vec3) -> Vec3 {
        Vec3::new(self.x - o.x, self.y - o.y, self.z - o.z)
    }
}

impl Mul<f64> for Vec3 {
    type Output = Vec3;
    fn mul(self, s: f64) -> Vec3 {
        Vec3::new(self.x * s, self.y * s, self.z * s)
    }
}

impl Neg for Vec3 {
    type Output = Vec3;
    fn neg(self) -> Vec3 {
        Vec3::new(-self.x, -self.y, -self.z)
    }
}

/// A coordinate axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Axis {
    /// The x axis.
    X,
    /// The y axis.
    Y,
    /// The z axis.
    Z,
}

impl Axis {
    /// Index 0, 1 or 2.
    pub fn index(self) -> usize {
        match self {
            Axis::X => 0,
            Axis::Y => 1,
            Axis::Z => 2,
        }
    }

    /// The unit vector along this axis.
    pub fn unit(self) -> Vec3 {
        match self {
            Axis::X => Vec3::new(1.0, 0.0, 0.0),
            Axis::Y => Vec3::new(0.0, 1.0, 0.0),
            Axis::Z => Vec3::new(0.0, 0.0, 1.0),
        }
    }

    /// Upper-case letter, as used in BVH channel names.
    pub fn letter(self) -> char {
        match self {
            Axis::X => 'X',
            Axis::Y => 'Y',
            Axis::Z => 'Z',
        }
    }

    /// Parses `x`/`X`, `y`/`Y`, `z`/`Z`.
    pub fn from_letter(c: char) -> Option<Axis> {
        match c {
            'x' | 'X' => Some(Axis::X),
            'y' | 'Y' => Some(Axis::Y),
            'z' | 'Z' => Some(Axis::Z),
            _ => None,
        }
    }
}

/// A rotation as a unit quaternion `w + xi + yj + zk`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Quat {
    /// Scalar part.
    pub w: f64,
    /// i component.
    pub x: f64,
    /// j component.
    pub y: f64,
    /// k component.
    pub z: f64,
}

impl Default for Quat {
    fn default() -> Self {
        Quat::IDENTITY
    }
}

impl Quat {
    /// The identity rotation.
    pub const IDENTITY: Quat = Quat { w: 1.0, x: 0.0, y: 0.0, z: 0.0 };

    /// Builds a quaternion from `w, x, y, z` without normalising it.
    pub const fn new(w: f64, x: f64, y: f64, z: f64) -> Self {
        Quat { w, x, y, z }
    }

    /// Rotation by `angle` radians about a unit `axis`.
    pub fn from_axis_angle(axis: Vec3, angle: f64) -> Quat {
        let (s, c) = (angle * 0.5).sin_cos();
        Quat::new(c, axis.x * s, axis.y * s, axis.z * s)
    }

    /// Rotation by `angle` radians about a coordinate axis.
    pub fn about(axis: Axis, angle: f64) -> Quat {
        Quat::from_axis_angle(axis.unit(), angle)
    }

    /// The inverse of a unit quaternion.
    pub fn conjugate(self) -> Quat {
        Quat::new(self.w, -self.x, -self.y, -self.z)
    }

    /// Four-dimensional dot product.
    pub fn dot(self, o: Quat) -> f64 {
        self.w * o.w + self.x * o.x + self.y * o.y + self.z * o.z
    }

    /// Euclidean norm of the four components.
    pub fn norm(self) -> f64 {
        self.dot(self).sqrt()
    }

    /// True when every component is finite.
    pub fn is_finite(self) -> bool {
        self.w.is_finite() && self.x.is_finite() && self.y.is_finite() && self.z.is_finite()
    }

    /// The quaternion scaled to unit length, or `None` if it is (nearly) zero or not finite.
    pub fn normalized(self) -> Option<Quat> {
        let n = self.norm();
        if !n.is_finite() || n < 1e-12 {
            return None;
        }
        Some(Quat::new(self.w / n, self.x / n, self.y / n, self.z / n))
    }

    /// Rotates a vector.
    pub fn rotate(self, v: Vec3) -> Vec3 {
        // v' = v + 2 u × (u × v + w v), with u the vector part.
        let u = Vec3::new(self.x, self.y, self.z);
        let t = u.cross(v) * 2.0;
        v + t * self.w + u.cross(t)
    }

    /// The rotation angle between two rotations in radians, in `[0, π]` (sign of `q` ignored).
    pub fn angle_to(self, o: Quat) -> f64 {
        let d = self.conjugate() * o;
        let v = (d.x * d.x + d.y * d.y + d.z * d.z).sqrt();
        2.0 * v.atan2(d.w.abs())
    }

    /// The rotation matrix, row-major (`m[row][col]`).
    pub fn to_matrix(self) -> [[f64; 3]; 3] {
        let Quat { w, x, y, z } = self;
        [
            [1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - w * z), 2.0 * (x * z + w * y)],
            [2.0 * (x * y + w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - w * x)],
            [2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y)],
        ]
    }

    /// Heading in radians: the angle about the `up` axis of this rotation's forward reference
    /// vector (+z for y-up, +x for z-up), positive counter-clockwise seen from above.
    ///
    /// For y-up data a positive change is a left turn when the character faces +z.
    pub fn heading(self, up: UpAxis) -> f64 {
        match up {
            UpAxis::Y => {
                let f = self.rotate(Vec3::new(0.0, 0.0, 1.0));
                f.x.atan2(f.z)
            }
            UpAxis::Z => {
                let f = self.rotate(Vec3::new(1.0, 0.0, 0.0));
                f.y.atan2(f.x)
            }
        }
    }
}

impl Mul for Quat {
    type Output = Quat;
    fn mul(self, o: Quat) -> Quat {
        Quat::new(
            self.w * o.w - self.x * o.x - self.y * o.y - self.z * o.z,
            self.w * o.x + self.x * o.w + self.y * o.z - self.z * o.y,
            self.w * o.y - self.x * o.z + self.y * o.w + self.z * o.x,
            self.w * o.z + self.x * o.y - self.y * o.x + self.z * o.w,
        )
    }
}

/// Which axis points up in a clip's own frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UpAxis {
    /// +y is up (BVH, DeepMimic, CMU ASF/AMC).
    Y,
    /// +z is up (MuJoCo).
    Z,
}

impl UpAxis {
    /// The up axis as an [`Axis`].
    pub fn axis(self) -> Axis {
        match self {
            UpAxis::Y => Axis::Y,
            UpAxis::Z => Axis::Z,
        }
    }
}

/// Three distinct axes naming an intrinsic Euler rotation `R = R_a(α) · R_b(β) · R_c(γ)`.
///
/// This is the BVH reading of a channel list such as `Zrotation Xrotation Yrotation`
/// (`[Z, X, Y]`). An ASF/AMC list that applies its first axis first (`XYZ` = `Rz Ry Rx`) is the
/// intrinsic order reversed, see [`EulerOrder::reversed`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct EulerOrder(pub [Axis; 3]);

impl EulerOrder {
    /// `Z X Y`, the CMU BVH order.
    pub const ZXY: EulerOrder = EulerOrder([Axis::Z, Axis::X, Axis::Y]);

    /// Builds an order, or `None` if an axis repeats.
    pub fn new(axes: [Axis; 3]) -> Option<EulerOrder> {
        let [a, b, c] = axes;
        (a != b && b != c && a != c).then_some(EulerOrder(axes))
    }

    /// Parses three letters such as `"XYZ"` (case-insensitive).
    pub fn parse(s: &str) -> Option<EulerOrder> {
        let mut it = s.chars().map(Axis::from_letter);
        let axes = [it.next()??, it.next()??, it.next()??];
        if it.next().is_some() {
            return None;
        }
        EulerOrder::new(axes)
    }

    /// The same axes in the opposite order.
    pub fn reversed(self) -> EulerOrder {
        let [a, b, c] = self.0;
        EulerOrder([c, b, a])
    }

    /// The rotation `R_a(angles[0]) · R_b(angles[1]) · R_c(angles[2])` (radians).
    pub fn to_quat(self, angles: [f64; 3]) -> Quat {
        let [a, b, c] = self.0;
        Quat::about(a, angles[0]) * Quat::about(b, angles[1]) * Quat::about(c, angles[2])
    }

    /// Angles `[α, β, γ]` (radians) with `to_quat(angles) == q`, `β ∈ [-π/2, π/2]`.
    ///
    /// At gimbal lock (`|β| = π/2`) `γ` is set to zero.
    pub fn from_quat(self, q: Quat) -> [f64; 3] {
        let m = q.to_matrix();
        let [i, j, k] = self.0.map(Axis::index);
        // +1 for the cyclic orders XYZ, YZX, ZXY; -1 for the others.
        let s = if (j + 3 - i) % 3 == 1 { 1.0 } else { -1.0 };
        let sb = (s * m[i][k]).clamp(-1.0, 1.0);
        let beta = sb.asin();
        let cb = (1.0 - sb * sb).max(0.0).sqrt();
        if cb > 1e-7 {
            let alpha = (-s * m[j][k]).atan2(m[k][k]);
            let gamma = (-s * m[i][j]).atan2(m[i][i]);
            [alpha, beta, gamma]
        } else {
            let alpha = (s * m[k][j]).atan2(m[j][j]);
            [alpha, beta, 0.0]
        }
    }

    /// Like [`EulerOrder::from_quat`], but of the two equivalent angle triples (and their
    /// 2π shifts) returns the one closest to `hint` (radians), for continuous curves.
    pub fn from_quat_near(self, q: Quat, hint: [f64; 3]) -> [f64; 3] {
        let a = self.from_quat(q);
        let b = [a[0] + PI, PI - a[1], a[2] + PI];
        let near = |sol: [f64; 3]| -> ([f64; 3], f64) {
            let mut out = sol;
            let mut cost = 0.0;
            for (o, h) in out.iter_mut().zip(hint) {
                *o = wrap_near(*o, h);
                cost += (*o - h).abs();
            }
            (out, cost)
        };
        let (sa, ca) = near(a);
        let (sb, cb) = near(b);
        if cb < ca { sb } else { sa }
    }
}

/// `angle + 2πk` for the integer `k` that brings it closest to `target`.
pub fn wrap_near(angle: f64, target: f64) -> f64 {
    if !target.is_finite() {
        return angle;
    }
    let k = ((target - angle) / (2.0 * PI)).round();
    angle + 2.0 * PI * k
}

#[cfg(test)]
mod tests {
    use super::*;

    const ALL_ORDERS: [[Axis; 3]; 6] = [
        [Axis::X, Axis::Y, Axis::Z],
        [Axis::X, Axis::Z, Axis::Y],
        [Axis::Y, Axis::X, Axis::Z],
        [Axis::Y, Axis::Z, Axis::X],
        [Axis::Z, Axis::X, Axis::Y],
        [Axis::Z, Axis::Y, Axis::X],
    ];

    fn close(a: Vec3, b: Vec3) -> bool {
        (a - b).norm() < 1e-12
    }

    #[test]
    fn quarter_turns_follow_the_right_hand_rule() {
        let h = std::f64::consts::FRAC_PI_2;
        let x = Axis::X.unit();
        let y = Axis::Y.unit();
        let z = Axis::Z.unit();
        assert!(close(Quat::about(Axis::Z, h).rotate(x), y));
        assert!(close(Quat::about(Axis::X, h).rotate(y), z));
        assert!(close(Quat::about(Axis::Y, h).rotate(z), x));
    }

    #[test]
    fn product_applies_right_factor_first() {
        let h = std::f64::consts::FRAC_PI_2;
        let q = Quat::about(Axis::Z, h) * Quat::about(Axis::X, h);
        // X first: y -> z; then Z: z stays z.
        assert!(close(q.rotate(Axis::Y.unit()), Axis::Z.unit()));
    }

    #[test]
    fn matrix_matches_rotate() {
        let q = EulerOrder::ZXY.to_quat([0.3, -1.1, 2.0]);
        let m = q.to_matrix();
        let v = Vec3::new(0.2, -0.7, 1.3);
        let r = q.rotate(v);
        let mv = Vec3::new(
            m[0][0] * v.x + m[0][1] * v.y + m[0][2] * v.z,
            m[1][0] * v.x + m[1][1] * v.y + m[1][2] * v.z,
            m[2][0] * v.x + m[2][1] * v.y + m[2][2] * v.z,
        );
        assert!(close(r, mv));
    }

    #[test]
    fn euler_round_trips_in_every_order() {
        for axes in ALL_ORDERS {
            let order = EulerOrder::new(axes).unwrap();
            for &angles in &[[0.1, 0.2, 0.3], [-2.5, 1.2, 3.0], [1.0, -1.5, -0.4]] {
                let q = order.to_quat(angles);
                let back = order.from_quat(q);
                assert!(order.to_quat(back).angle_to(q) < 1e-9, "{axes:?}");
                for (a, b) in back.iter().zip(angles) {
                    assert!((a - b).abs() < 1e-9, "{axes:?} {back:?} {angles:?}");
                }
            }
        }
    }

    #[test]
    fn euler_at_gimbal_lock_still_reproduces_the_rotation() {
        for axes in ALL_ORDERS {
            let order = EulerOrder::new(axes).unwrap();
            for beta in [std::f64::consts::FRAC_PI_2, -std::f64::consts::FRAC_PI_2] {
                let q = order.to_quat([0.4, beta, -0.9]);
                let back = order.from_quat(q);
                assert!(order.to_quat(back).angle_to(q) < 1e-6, "{axes:?}");
            }
        }
    }

    #[test]
    fn near_solution_recovers_out_of_range_angles() {
        let order = EulerOrder::ZXY;
        let angles = [3.5, 2.0, -4.0]; // middle angle beyond π/2, others beyond π
        let q = order.to_quat(angles);
        let back = order.from_quat_near(q, [3.4, 2.1, -3.9]);
        for (a, b) in back.iter().zip(angles) {
            assert!((a - b).abs() < 1e-9, "{back:?}");
        }
    }

    #[test]
    fn heading_is_positive_for_a_left_turn_about_y() {
        let q = Quat::about(Axis::Y, 0.5);
        assert!((q.heading(UpAxis::Y) - 0.5).abs() < 1e-12);
        let q = Quat::about(Axis::Z, -0.25);
        assert!((q.heading(UpAxis::Z) + 0.25).abs() < 1e-12);
    }

    #[test]
    fn parse_order() {
        assert_eq!(EulerOrder::parse("zxy"), Some(EulerOrder::ZXY));
        assert_eq!(EulerOrder::parse("XXY"), None);
        assert_eq!(EulerOrder::parse("XY"), None);
        assert_eq!(EulerOrder::parse("XYZW"), None);
    }
}
