//! Physical units of parameters and outputs, as SI exponents.

/// Physical units, as SI exponents (kg, m, s, rad).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Unit {
    One,
    Metre,
    Second,
    MetrePerSecond,
    MetrePerSecond2,
    Newton,
    NewtonPerMetre,
    /// The stiffness `K` of a power-law force `K p^n`, N / m^n (Hertz:
    /// n = 1.5; no integer SI exponents unless n is an integer); made by
    /// [`Unit::power_stiffness`].
    NewtonPerMetrePower(Exponent),
    NewtonMetre,
    Joule,
    RadianPerSecond,
    NewtonSecondPerMetre,
    NewtonSecond,
    /// Viscous damping per unit length, N s / m^2.
    NewtonSecondPerMetre2,
    Radian,
    /// Moment of inertia, kg m^2.
    KilogramMetre2,
    /// Controller gains: torque per angle, per angular speed, per angle
    /// and time; and an angle integrated over time.
    NewtonMetrePerRadian,
    NewtonMetreSecondPerRadian,
    NewtonMetrePerRadianSecond,
    RadianSecond,
}

/// The exponent `n` of a power-law stiffness's unit N/m^n (its bits, so
/// that units compare, hash and sort; positive, so in numeric order).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Exponent(u64);

impl Exponent {
    pub const fn of(n: f64) -> Exponent {
        Exponent(n.to_bits())
    }

    pub fn value(self) -> f64 {
        f64::from_bits(self.0)
    }
}

impl Unit {
    /// N/m^n: N/m at n = 1, else [`Unit::NewtonPerMetrePower`].
    pub fn power_stiffness(n: f64) -> Unit {
        if n == 1.0 {
            Unit::NewtonPerMetre
        } else {
            Unit::NewtonPerMetrePower(Exponent(n.to_bits()))
        }
    }

    pub fn name(self) -> std::borrow::Cow<'static, str> {
        if let Unit::NewtonPerMetrePower(n) = self {
            return format!("N/m{}", n.value()).into();
        }
        std::borrow::Cow::Borrowed(match self {
            Unit::One => "1",
            Unit::Metre => "m",
            Unit::Second => "s",
            Unit::MetrePerSecond => "m/s",
            Unit::MetrePerSecond2 => "m/s2",
            Unit::Newton => "N",
            Unit::NewtonPerMetre => "N/m",
            Unit::NewtonMetre => "N.m",
            Unit::Joule => "J",
            Unit::RadianPerSecond => "rad/s",
            Unit::NewtonSecondPerMetre => "N.s/m",
            Unit::NewtonSecond => "N.s",
            Unit::NewtonSecondPerMetre2 => "N.s/m2",
            Unit::Radian => "rad",
            Unit::KilogramMetre2 => "kg.m2",
            Unit::NewtonMetrePerRadian => "N.m/rad",
            Unit::NewtonMetreSecondPerRadian => "N.m.s/rad",
            Unit::NewtonMetrePerRadianSecond => "N.m/(rad.s)",
            Unit::RadianSecond => "rad.s",
            Unit::NewtonPerMetrePower(_) => unreachable!("named above"),
        })
    }

    /// Exponents of kg, m, s, rad (`None`: not integer, as N/m^1.5).
    pub fn si_exponents(self) -> Option<[i32; 4]> {
        Some(match self {
            Unit::NewtonPerMetrePower(n) => {
                let n = n.value();
                return (n.fract() == 0.0 && n.abs() < 64.0).then(|| [1, 1 - n as i32, -2, 0]);
            }
            Unit::One => [0, 0, 0, 0],
            Unit::Metre => [0, 1, 0, 0],
            Unit::Second => [0, 0, 1, 0],
            Unit::MetrePerSecond => [0, 1, -1, 0],
            Unit::MetrePerSecond2 => [0, 1, -2, 0],
            Unit::Newton => [1, 1, -2, 0],
            Unit::NewtonPerMetre => [1, 0, -2, 0],
            Unit::NewtonMetre | Unit::Joule => [1, 2, -2, 0],
            Unit::RadianPerSecond => [0, 0, -1, 1],
            Unit::NewtonSecondPerMetre => [1, 0, -1, 0],
            Unit::NewtonSecond => [1, 1, -1, 0],
            Unit::NewtonSecondPerMetre2 => [1, -1, -1, 0],
            Unit::Radian => [0, 0, 0, 1],
            Unit::KilogramMetre2 => [1, 2, 0, 0],
            Unit::NewtonMetrePerRadian => [1, 2, -2, -1],
            Unit::NewtonMetreSecondPerRadian => [1, 2, -1, -1],
            Unit::NewtonMetrePerRadianSecond => [1, 2, -3, -1],
            Unit::RadianSecond => [0, 0, 1, 1],
        })
    }
}

