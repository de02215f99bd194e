#![doc = include_str!("../derivation.md")]
#![deny(unsafe_code)]

use fmu_export::nalgebra::{Matrix3, Vector2, Vector3};
use fmu_export::scalar::length;
use fmu_export::{Equations, EventOutcome, Model, ModelError, ModelInfo, Scalar, StateVector, Variables};
use serde::{Deserialize, Serialize};

use fmu_export::units::{DEGREE as DEG, FOOT, INCH, LBF, OZF};

/// The regimes of Ex. 6, numbered as the `regime` output gives them. The impact is
/// instantaneous: it happens inside the event handler at `t_impact`, so sampled outputs show
/// `Falling`, then `Swinging` and `Flying`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Regime {
    /// Regime 1: the mechanism falls as one rigid body about D on the ground.
    Falling = 1,
    /// Regime 2: A hits the ground (instantaneous).
    Impact = 2,
    /// Regime 3: the links swing about A, the projectile on its cord.
    Swinging = 3,
    /// Regime 4: the projectile flies free; the mechanism is frozen.
    Flying = 4,
}

impl From<Regime> for i32 {
    fn from(regime: Regime) -> i32 {
        regime as i32
    }
}

/// The unit vector u = (cos theta, sin theta) of a link at angle `theta`.
fn unit<T: Scalar>(theta: T) -> Vector2<T> {
    Vector2::new(theta.cos(), theta.sin())
}

/// The unit vector p = (-sin theta, cos theta), u turned by +90 degrees: a point at distance r
/// along u moves at r theta' p.
fn perp<T: Scalar>(theta: T) -> Vector2<T> {
    Vector2::new(-theta.sin(), theta.cos())
}

/// The midpoint of `p` and `q`.
fn midpoint<T: Scalar>(p: Vector2<T>, q: Vector2<T>) -> Vector2<T> {
    (p + q) * T::from(0.5)
}

/// Masses and inertias derived from Table 6.1 (derivation.md, "Bodies").
#[derive(Debug, Clone, Copy)]
pub struct Inertia<T> {
    /// Link 1 (rod AC), link 2 (rod BD + counterweight), projectile (kg).
    pub m1: T,
    pub m2: T,
    pub m3: T,
    /// Position of G along B->D measured from C (m, negative: toward B).
    pub s_g: T,
    /// Centroidal moments of inertia of links 1 and 2 (kg m^2).
    pub i1: T,
    pub i2: T,
}

/// Positions and velocities of the mechanism's points and its angular velocities.
#[derive(Debug, Clone, Copy)]
pub struct Frame<T> {
    pub a: Vector2<T>,
    pub b: Vector2<T>,
    pub c: Vector2<T>,
    pub d: Vector2<T>,
    pub e: Vector2<T>,
    /// Centre of link 1 (midpoint of AC).
    pub f: Vector2<T>,
    /// Centre of link 2 with the counterweight.
    pub g: Vector2<T>,
    pub v_f: Vector2<T>,
    pub v_g: Vector2<T>,
    pub v_e: Vector2<T>,
    pub v_d: Vector2<T>,
    /// The angular velocities of the links (the cord's as the third).
    pub w: [T; 3],
}

/// Ex. 6: the walking arm trebuchet.
#[derive(Debug, Clone, Serialize, Deserialize, Variables)]
#[serde(bound(serialize = "T: Serialize + Scalar", deserialize = "T: Deserialize<'de> + Scalar"))]
#[variables(states = State)]
pub struct Trebuchet<T = f64> {
    /// Length of link 1, AC
    #[parameter(name = "r_AC", unit = "m", display = "in", positive)]
    pub r_ac: T,
    /// Length BC of link 2 (counterweight B to pin C)
    #[parameter(name = "r_BC", unit = "m", display = "in", positive)]
    pub r_bc: T,
    /// Length CD of link 2 (pin C to tip D)
    #[parameter(name = "r_CD", unit = "m", display = "in", positive)]
    pub r_cd: T,
    /// Length of the cord DE (link 3)
    #[parameter(name = "r_DE", unit = "m", display = "in", positive)]
    pub r_de: T,
    /// Weight per unit length of the rods AC and BD
    #[parameter(unit = "N/m", display = "lbf/ft", positive)]
    pub rho: T,
    /// Weight of the counterweight at B
    #[parameter(name = "w_B", unit = "N", display = "lbf", positive)]
    pub w_b: T,
    /// Weight of the projectile at E
    #[parameter(unit = "N", display = "ozf", positive)]
    pub w_3: T,
    /// Gravitational acceleration
    #[parameter(unit = "m/s2", positive)]
    pub g: T,
    /// Initial angle of A->C from +x
    #[parameter(unit = "rad", display = "deg", finite)]
    pub theta1_0: T,
    /// Initial angle of B->D from +x
    #[parameter(unit = "rad", display = "deg", finite)]
    pub theta2_0: T,
    /// Initial angle of D->E from +x
    #[parameter(unit = "rad", display = "deg", finite)]
    pub theta3_0: T,
    /// Release when theta3 - theta2 exceeds this
    #[parameter(unit = "rad", display = "deg", finite)]
    pub release_angle: T,
    /// 1 falling, 2 impact (instantaneous), 3 swinging, 4 flying
    #[output(integer)]
    pub regime: Regime,
    /// x and y of A
    #[output(name = "A", unit = "m")]
    pub a: Vector2<T>,
    /// x and y of B (counterweight)
    #[output(name = "B", unit = "m")]
    pub b: Vector2<T>,
    /// x and y of C (pin between links 1 and 2)
    #[output(name = "C", unit = "m")]
    pub c: Vector2<T>,
    /// x and y of D (tip of link 2)
    #[output(name = "D", unit = "m")]
    pub d: Vector2<T>,
    /// x and y of E (projectile)
    #[output(name = "E", unit = "m")]
    pub e: Vector2<T>,
    /// Speed of the projectile
    #[output(unit = "m/s")]
    pub projectile_speed: T,
    /// Total mechanical energy, datum y = 0 (after release: links frozen at their release
    /// energy + projectile)
    #[output(unit = "J")]
    pub energy: T,
    /// Time A hit the ground (regime 2), -1 until then
    #[output(unit = "s", discrete)]
    pub t_impact: T,
    /// Time of release, -1 until then
    #[output(unit = "s", discrete)]
    pub t_release: T,
    /// Landing x of the projectile, 0 until it has landed
    #[output(unit = "m", discrete)]
    pub range: T,
    /// All initial potential energy (datum y = 0) given to the projectile at 45 deg: v^2/g
    #[output(unit = "m", discrete)]
    pub range_ideal: T,
    /// Projectile kinetic energy at release / initial potential energy (datum y = 0); 0
    /// before release
    #[output(unit = "1", discrete)]
    pub efficiency: T,
    /// True: B reached the ground before release
    #[output]
    pub misfire: bool,
    /// x of A once it is the fixed pivot (regimes 3 and 4).
    pub pivot_x: T,
    /// Energy of links 1 and 2 at release (they are frozen afterwards), J.
    pub e_links_release: T,
    /// The initial potential energy (datum y = 0), J.
    pub pe0: T,
}

/// The state vector (10 components, all regimes; derivation.md, "State vector").
#[derive(StateVector, Debug, Clone, Copy)]
pub struct State<T = f64> {
    /// Angle of A->C from +x (frozen after release)
    #[state(unit = "rad", display = "deg")]
    pub theta1: T,
    /// Angle of B->D from +x (frozen after release)
    #[state(unit = "rad", display = "deg")]
    pub theta2: T,
    /// Angle of D->E from +x (frozen after release)
    #[state(unit = "rad", display = "deg")]
    pub theta3: T,
    /// Rate of theta1 (regime 1: the common rate about D)
    #[state(unit = "rad/s")]
    pub omega1: T,
    /// Rate of theta2 (regime 1: the common rate about D)
    #[state(unit = "rad/s")]
    pub omega2: T,
    /// Rate of theta3 (regime 1: the common rate about D)
    #[state(unit = "rad/s")]
    pub omega3: T,
    /// Projectile x in flight (0 before release)
    #[state(unit = "m")]
    pub x_p: T,
    /// Projectile y in flight (0 before release)
    #[state(unit = "m")]
    pub y_p: T,
    /// Projectile x velocity in flight (0 before release)
    #[state(unit = "m/s")]
    pub vx_p: T,
    /// Projectile y velocity in flight (0 before release)
    #[state(unit = "m/s")]
    pub vy_p: T,
}

impl<T: Scalar> State<T> {
    /// The link angles [theta1, theta2, theta3] (Lagrange's generalized coordinates).
    fn angles(&self) -> [T; 3] {
        [self.theta1, self.theta2, self.theta3]
    }

    /// Their rates [omega1, omega2, omega3].
    fn rates(&self) -> [T; 3] {
        [self.omega1, self.omega2, self.omega3]
    }

    /// All zero: the state's derivative before the regime fills it.
    fn zero() -> State<T> {
        let z = T::zero();
        State { theta1: z, theta2: z, theta3: z, omega1: z, omega2: z, omega3: z, x_p: z, y_p: z, vx_p: z, vy_p: z }
    }
}

impl Default for Trebuchet {
    fn default() -> Self {
        let mut m = Trebuchet {
            r_ac: 20.0 * INCH,
            r_bc: 15.0 * INCH,
            r_cd: 20.0 * INCH,
            r_de: 18.0 * INCH,
            rho: 0.7 * LBF / FOOT,
            w_b: 20.0 * LBF,
            w_3: 4.0 * OZF,
            g: 9.81,
            theta1_0: 50.0 * DEG,
            theta2_0: -60.0 * DEG,
            theta3_0: 10.0 * DEG,
            release_angle: 140.0 * DEG,
            regime: Regime::Falling,
            a: Vector2::zeros(),
            b: Vector2::zeros(),
            c: Vector2::zeros(),
            d: Vector2::zeros(),
            e: Vector2::zeros(),
            projectile_speed: 0.0,
            energy: 0.0,
            t_impact: -1.0,
            t_release: -1.0,
            range: 0.0,
            range_ideal: 0.0,
            efficiency: 0.0,
            misfire: false,
            pivot_x: 0.0,
            e_links_release: 0.0,
            pe0: 0.0,
        };
        let mut x = [0.0; State::LEN];
        m.initial_state(&mut x).expect("the defaults are valid");
        m.outputs(0.0, &x);
        m
    }
}

impl<T: Scalar> Trebuchet<T> {
    /// Masses, centre G and inertias of the three bodies.
    pub fn inertia(&self) -> Inertia<T> {
        let g = self.g;
        let m1 = self.rho * self.r_ac / g;
        let m_rod = self.rho * (self.r_bc + self.r_cd) / g;
        let m_b = self.w_b / g;
        let m2 = m_rod + m_b;
        let s_rod = (self.r_cd - self.r_bc) * 0.5;
        let s_g = (m_rod * s_rod - m_b * self.r_bc) / m2;
        let l2 = self.r_bc + self.r_cd;
        // About G: rod about its own centre, shifted to G; counterweight at B.
        let i2 = m_rod * (l2 * l2 / 12.0 + (s_rod - s_g).powi(2)) + m_b * (self.r_bc + s_g).powi(2);
        Inertia { m1, m2, m3: self.w_3 / g, s_g, i1: m1 * self.r_ac * self.r_ac / 12.0, i2 }
    }

    /// Points and velocities of the mechanism in `regime` (falling: pivot D at the origin,
    /// rigid rotation at omega1; swinging and flying: pivot A at (pivot_x, 0), rates omega1..3;
    /// flying, the mechanism is frozen at its release configuration and E is the free
    /// projectile).
    pub fn frame(&self, regime: Regime, x: &State<T>) -> Frame<T> {
        let (a, b, c, e) = (self.r_ac, self.r_bc, self.r_cd, self.r_de);
        let s_g = self.inertia().s_g;
        let (u1, u2, u3) = (unit(x.theta1), unit(x.theta2), unit(x.theta3));
        let zero = Vector2::zeros();
        if regime == Regime::Falling {
            // One rigid body turning at omega about D: v_P = omega k x P.
            let w = x.omega1;
            let d = zero;
            let c = u2 * -c;
            let pa = c - u1 * a;
            let pe = u3 * e;
            let f = midpoint(pa, c);
            let g = c + u2 * s_g;
            let velocity = |p: Vector2<T>| Vector2::new(-w * p.y, w * p.x);
            Frame {
                a: pa,
                b: c - u2 * b,
                c,
                d,
                e: pe,
                f,
                g,
                v_f: velocity(f),
                v_g: velocity(g),
                v_e: velocity(pe),
                v_d: zero,
                w: [w, w, w],
            }
        } else {
            let frozen = regime == Regime::Flying;
            let w = if frozen { [T::zero(); 3] } else { x.rates() };
            let pa = Vector2::new(self.pivot_x, T::zero());
            let pc = pa + u1 * a;
            let pd = pc + u2 * c;
            let v_c = perp(x.theta1) * (a * w[0]);
            let v_d = v_c + perp(x.theta2) * (c * w[1]);
            let mut fr = Frame {
                a: pa,
                b: pc - u2 * b,
                c: pc,
                d: pd,
                e: pd + u3 * e,
                f: midpoint(pa, pc),
                g: pc + u2 * s_g,
                v_f: v_c * T::from(0.5),
                v_g: v_c + perp(x.theta2) * (s_g * w[1]),
                v_e: v_d + perp(x.theta3) * (e * w[2]),
                v_d,
                w,
            };
            if frozen {
                fr.e = Vector2::new(x.x_p, x.y_p);
                fr.v_e = Vector2::new(x.vx_p, x.vy_p);
            }
            fr
        }
    }

    /// Kinetic + potential energy of links 1 and 2 (datum y = 0).
    fn links_energy(&self, fr: &Frame<T>) -> T {
        let m = self.inertia();
        m.m1 * 0.5 * fr.v_f.dot(&fr.v_f)
            + m.i1 * 0.5 * fr.w[0] * fr.w[0]
            + m.m2 * 0.5 * fr.v_g.dot(&fr.v_g)
            + m.i2 * 0.5 * fr.w[1] * fr.w[1]
            + self.g * (m.m1 * fr.f.y + m.m2 * fr.g.y)
    }

    /// Kinetic + potential energy of the projectile (datum y = 0).
    fn projectile_energy(&self, fr: &Frame<T>) -> T {
        let m3 = self.w_3 / self.g;
        m3 * 0.5 * fr.v_e.dot(&fr.v_e) + self.w_3 * fr.e.y
    }

    /// The three impact momenta [H_A (whole system about A), H_C (links 2 and 3 about C),
    /// H_D (projectile about D)] of a configuration `fr` with body velocities given (r x v is
    /// the perpendicular product `r.perp(&v)`).
    pub fn impact_momenta(&self, fr: &Frame<T>, v_f: Vector2<T>, w1: T, v_g: Vector2<T>, w2: T, v_e: Vector2<T>) -> Vector3<T> {
        let m = self.inertia();
        let h_c = m.i2 * w2 + m.m2 * (fr.g - fr.c).perp(&v_g) + m.m3 * (fr.e - fr.c).perp(&v_e);
        let h_a =
            m.i1 * w1 + m.m1 * (fr.f - fr.a).perp(&v_f) + m.i2 * w2 + m.m2 * (fr.g - fr.a).perp(&v_g) + m.m3 * (fr.e - fr.a).perp(&v_e);
        let h_d = m.m3 * (fr.e - fr.d).perp(&v_e);
        Vector3::new(h_a, h_c, h_d)
    }

    /// Regime 2: the angular velocities just after A hits the ground (derivation.md): the
    /// momenta are linear in them, K w' = H(before), column j of K the momenta for w' = e_j.
    pub fn impact(&self, x: &State<T>) -> Vector3<T> {
        let pre = self.frame(Regime::Falling, x);
        let before = self.impact_momenta(&pre, pre.v_f, pre.w[0], pre.v_g, pre.w[1], pre.v_e);
        let (a, c, e) = (self.r_ac, self.r_cd, self.r_de);
        let s_g = self.inertia().s_g;
        let (p1, p2, p3) = (perp(x.theta1), perp(x.theta2), perp(x.theta3));
        let mut k = Matrix3::zeros();
        for j in 0..3 {
            let mut w = [T::zero(); 3];
            w[j] = T::one();
            let v_c = p1 * (a * w[0]);
            let v_g = v_c + p2 * (s_g * w[1]);
            let v_e = v_c + p2 * (c * w[1]) + p3 * (e * w[2]);
            k.set_column(j, &self.impact_momenta(&pre, v_c * T::from(0.5), w[0], v_g, w[1], v_e));
        }
        k.lu().solve(&before).unwrap_or_else(|| Vector3::repeat(T::from(f64::NAN)))
    }

    /// Regime 3: angular accelerations from M(theta) theta'' = -h(theta, theta') - dV/dtheta.
    pub fn swing_accelerations(&self, x: &State<T>) -> Vector3<T> {
        let m = self.inertia();
        let (a, c, e) = (self.r_ac, self.r_cd, self.r_de);
        let k = Matrix3::new(
            m.m1 * a * a / 3.0 + (m.m2 + m.m3) * a * a,
            (m.m2 * m.s_g + m.m3 * c) * a,
            m.m3 * a * e,
            (m.m2 * m.s_g + m.m3 * c) * a,
            m.i2 + m.m2 * m.s_g * m.s_g + m.m3 * c * c,
            m.m3 * c * e,
            m.m3 * a * e,
            m.m3 * c * e,
            m.m3 * e * e,
        );
        let gv = [self.g * (m.m1 * 0.5 + m.m2 + m.m3) * a, self.g * (m.m2 * m.s_g + m.m3 * c), self.g * m.m3 * e];
        let (theta, omega) = (x.angles(), x.rates());
        let mut mass = Matrix3::zeros();
        let mut rhs = Vector3::zeros();
        for i in 0..3 {
            let mut h = T::zero();
            for j in 0..3 {
                let d = theta[i] - theta[j];
                mass[(i, j)] = k[(i, j)] * d.cos();
                h += k[(i, j)] * d.sin() * omega[j] * omega[j];
            }
            rhs[i] = -h - gv[i] * theta[i].cos();
        }
        mass.cholesky().map(|ch| ch.solve(&rhs)).unwrap_or_else(|| Vector3::repeat(T::from(f64::NAN)))
    }

    /// Regime 1: the angular acceleration of the rigid mechanism about D.
    pub fn fall_acceleration(&self, x: &State<T>) -> T {
        let m = self.inertia();
        let fr = self.frame(Regime::Falling, x);
        let i_d = m.i1 + m.m1 * fr.f.dot(&fr.f) + m.i2 + m.m2 * fr.g.dot(&fr.g) + m.m3 * fr.e.dot(&fr.e);
        -self.g * (m.m1 * fr.f.x + m.m2 * fr.g.x + m.m3 * fr.e.x) / i_d
    }
}

impl<T: Scalar> Equations<T> for Trebuchet<T> {
    fn initial_state(&mut self, x: &mut [T]) -> Result<(), ModelError> {
        if self.release_angle <= self.theta3_0 - self.theta2_0 {
            return Err(ModelError(format!(
                "parameter release_angle = {} must exceed theta3_0 - theta2_0 = {} (theta3 - theta2 is constant until the impact)",
                self.release_angle.value(),
                (self.theta3_0 - self.theta2_0).value()
            )));
        }
        let start = State { theta1: self.theta1_0, theta2: self.theta2_0, theta3: self.theta3_0, ..State::zero() };
        start.store(x);
        self.regime = Regime::Falling;
        let fr = self.frame(Regime::Falling, &start);
        if fr.a.y <= T::zero() {
            return Err(ModelError(format!(
                "the starting configuration puts A at y = {} m: it must be above the ground (theta1_0, theta2_0)",
                fr.a.y.value()
            )));
        }
        if fr.b.y <= T::zero() {
            return Err(ModelError(format!(
                "the starting configuration puts B at y = {} m: it must be above the ground (theta2_0)",
                fr.b.y.value()
            )));
        }
        self.pivot_x = T::zero();
        self.misfire = false;
        self.t_impact = T::from(-1.0);
        self.t_release = T::from(-1.0);
        self.range = T::zero();
        self.e_links_release = T::zero();
        self.efficiency = T::zero();
        self.pe0 = self.links_energy(&fr) + self.projectile_energy(&fr);
        self.range_ideal = self.pe0 * 2.0 / self.w_3;
        Ok(())
    }

    fn derivatives(&self, _t: T, x: &[T], dx: &mut [T]) {
        let s = State::load(x);
        let rate = match self.regime {
            Regime::Falling => {
                // One rigid body: every angle turns at omega1, every rate gains alpha.
                let (w, alpha) = (s.omega1, self.fall_acceleration(&s));
                State { theta1: w, theta2: w, theta3: w, omega1: alpha, omega2: alpha, omega3: alpha, ..State::zero() }
            }
            Regime::Swinging => {
                let acc = self.swing_accelerations(&s);
                State { theta1: s.omega1, theta2: s.omega2, theta3: s.omega3, omega1: acc.x, omega2: acc.y, omega3: acc.z, ..State::zero() }
            }
            // The projectile flies; the mechanism is frozen.
            Regime::Flying | Regime::Impact => State { x_p: s.vx_p, y_p: s.vy_p, vy_p: -self.g, ..State::zero() },
        };
        rate.store(dx);
    }

    fn outputs(&mut self, _t: T, x: &[T]) {
        let fr = self.frame(self.regime, &State::load(x));
        (self.a, self.b, self.c, self.d, self.e) = (fr.a, fr.b, fr.c, fr.d, fr.e);
        self.projectile_speed = length(&fr.v_e, 0.0);
        let links = if self.regime == Regime::Flying { self.e_links_release } else { self.links_energy(&fr) };
        self.energy = links + self.projectile_energy(&fr);
    }
}

impl Model for Trebuchet {
    const N_STATES: usize = State::LEN;
    const N_EVENT_INDICATORS: usize = 3;

    fn info() -> ModelInfo {
        ModelInfo {
            identifier: "trebuchet",
            description: "ME326 Ex. 6: walking arm trebuchet - falling, impact, swinging and flying until the projectile lands",
            stop_time: 10.0,
            tolerance: 1e-6,
            output_interval: 1e-3,
            documentation: include_str!("../derivation.md"),
        }
    }

    /// [A_y while falling, B_y before the release (misfire), the release angle's margin
    /// while swinging or y_p in flight]; 1 where an indicator cannot fire.
    fn event_indicators(&self, _t: f64, x: &[f64], z: &mut [f64]) {
        let s = State::load(x);
        let fr = self.frame(self.regime, &s);
        z[0] = if self.regime == Regime::Falling { fr.a.y } else { 1.0 };
        z[1] = if matches!(self.regime, Regime::Falling | Regime::Swinging) { fr.b.y } else { 1.0 };
        z[2] = match self.regime {
            Regime::Swinging => self.release_angle - (s.theta3 - s.theta2),
            Regime::Flying => s.y_p,
            _ => 1.0,
        };
    }

    fn on_event(&mut self, t: f64, x: &mut [f64], fired: &[bool]) -> Result<EventOutcome, ModelError> {
        if fired[1] && matches!(self.regime, Regime::Falling | Regime::Swinging) {
            self.misfire = true;
            return Ok(EventOutcome::Stop {
                reason: format!(
                    "misfire: the counterweight B reached the ground at t = {t:.6} s, before the release (regime {})",
                    i32::from(self.regime)
                ),
            });
        }
        let mut s = State::load(x);
        match self.regime {
            Regime::Falling if fired[0] => {
                // Regime 2, the impact: A becomes the fixed pivot, D leaves the ground.
                self.regime = Regime::Impact;
                let w = self.impact(&s);
                if w.iter().any(|v| !v.is_finite()) {
                    return Err(ModelError(format!("the impact equations are singular at t = {t}")));
                }
                self.pivot_x = self.frame(Regime::Falling, &s).a.x;
                (s.omega1, s.omega2, s.omega3) = (w.x, w.y, w.z);
                self.t_impact = t;
                self.regime = Regime::Swinging;
            }
            Regime::Swinging if fired[2] => {
                let fr = self.frame(Regime::Swinging, &s);
                self.e_links_release = self.links_energy(&fr);
                let m3 = self.w_3 / self.g;
                self.efficiency = 0.5 * m3 * fr.v_e.dot(&fr.v_e) / self.pe0;
                (s.x_p, s.y_p, s.vx_p, s.vy_p) = (fr.e.x, fr.e.y, fr.v_e.x, fr.v_e.y);
                self.t_release = t;
                self.regime = Regime::Flying;
            }
            Regime::Flying if fired[2] => {
                // Located to 1e-10 s, y_p is ~0: the last bit to y = 0 along the velocity.
                let tau = if s.vy_p != 0.0 { -s.y_p / s.vy_p } else { 0.0 };
                self.range = s.x_p + s.vx_p * tau;
                return Ok(EventOutcome::Stop { reason: format!("the projectile landed at x = {:.6} m", self.range) });
            }
            _ => {}
        }
        s.store(x);
        Ok(EventOutcome::Continue)
    }
}

fmu_export::export_fmu!(Trebuchet);

#[cfg(test)]
mod tests {
    use super::*;
    use fmu_export::harness::Harness;
    use formulas::References;

    const G: f64 = 9.81;

    fn tight(params: &[(&str, f64)]) -> Harness<Trebuchet> {
        let mut all = params.to_vec();
        all.push(("abs_tol", 1e-12));
        Harness::started(&all, Some(1e-10)).unwrap()
    }

    fn pt(h: &mut Harness<Trebuchet>, p: &str) -> [f64; 2] {
        [h.get(&format!("{p}_x")).unwrap(), h.get(&format!("{p}_y")).unwrap()]
    }

    /// The test's own mechanics, from the FMU's point outputs A..E and its rate states only:
    /// masses from Table 6.1 (defaults), F the midpoint of AC, G the composite centre of rod BD
    /// and the counterweight, velocities from rigid-body kinematics v_P = v_Q + w x (P - Q)
    /// about the fixed pivot (D in regime 1, A in regime 3).
    struct Snapshot {
        m: [f64; 3],
        i: [f64; 2],
        a: [f64; 2],
        c: [f64; 2],
        d: [f64; 2],
        e: [f64; 2],
        f: [f64; 2],
        g: [f64; 2],
        v_f: [f64; 2],
        v_g: [f64; 2],
        v_e: [f64; 2],
        w: [f64; 3],
    }

    fn snapshot(h: &mut Harness<Trebuchet>) -> Snapshot {
        let p = Trebuchet::default();
        let regime = h.get("regime").unwrap() as i32;
        let (a, b, c, d, e) = (pt(h, "A"), pt(h, "B"), pt(h, "C"), pt(h, "D"), pt(h, "E"));
        let w = [h.get("omega1").unwrap(), h.get("omega2").unwrap(), h.get("omega3").unwrap()];
        let m1 = p.rho * p.r_ac / G;
        let m_rod = p.rho * (p.r_bc + p.r_cd) / G;
        let m_b = p.w_b / G;
        let m2 = m_rod + m_b;
        // Rod centre is the midpoint of BD; G weights it with the point mass at B.
        let rod = [(b[0] + d[0]) / 2.0, (b[1] + d[1]) / 2.0];
        let g = [(m_rod * rod[0] + m_b * b[0]) / m2, (m_rod * rod[1] + m_b * b[1]) / m2];
        let f = [(a[0] + c[0]) / 2.0, (a[1] + c[1]) / 2.0];
        let l = p.r_bc + p.r_cd;
        let dist2 = |p: [f64; 2], q: [f64; 2]| (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2);
        let i2 = m_rod * (l * l / 12.0 + dist2(rod, g)) + m_b * dist2(b, g);
        let rot = |w: f64, p: [f64; 2], q: [f64; 2]| [-w * (p[1] - q[1]), w * (p[0] - q[0])];
        let (v_f, v_g, v_e) = if regime == 1 {
            (rot(w[0], f, d), rot(w[0], g, d), rot(w[0], e, d))
        } else {
            let v_c = rot(w[0], c, a);
            let v_g = {
                let r = rot(w[1], g, c);
                [v_c[0] + r[0], v_c[1] + r[1]]
            };
            let v_d = {
                let r = rot(w[1], d, c);
                [v_c[0] + r[0], v_c[1] + r[1]]
            };
            let v_e = {
                let r = rot(w[2], e, d);
                [v_d[0] + r[0], v_d[1] + r[1]]
            };
            (rot(w[0], f, a), v_g, v_e)
        };
        Snapshot { m: [m1, m2, p.w_3 / G], i: [m1 * p.r_ac * p.r_ac / 12.0, i2], a, c, d, e, f, g, v_f, v_g, v_e, w }
    }

    impl Snapshot {
        fn energy(&self) -> f64 {
            let ke = |m: f64, v: [f64; 2]| 0.5 * m * (v[0] * v[0] + v[1] * v[1]);
            ke(self.m[0], self.v_f)
                + ke(self.m[1], self.v_g)
                + ke(self.m[2], self.v_e)
                + 0.5 * self.i[0] * self.w[0].powi(2)
                + 0.5 * self.i[1] * self.w[1].powi(2)
                + G * (self.m[0] * self.f[1] + self.m[1] * self.g[1] + self.m[2] * self.e[1])
        }

        /// [whole system about A, links 2 + 3 about C, projectile about D].
        fn momenta(&self) -> [f64; 3] {
            let h = |m: f64, p: [f64; 2], q: [f64; 2], v: [f64; 2]| m * ((p[0] - q[0]) * v[1] - (p[1] - q[1]) * v[0]);
            let (m1, m2, m3) = (self.m[0], self.m[1], self.m[2]);
            let h_c = self.i[1] * self.w[1] + h(m2, self.g, self.c, self.v_g) + h(m3, self.e, self.c, self.v_e);
            let h_a = self.i[0] * self.w[0]
                + h(m1, self.f, self.a, self.v_f)
                + self.i[1] * self.w[1]
                + h(m2, self.g, self.a, self.v_g)
                + h(m3, self.e, self.a, self.v_e);
            [h_a, h_c, h(m3, self.e, self.d, self.v_e)]
        }
    }

    /// t_impact and t_release of the default launch at tight tolerance.
    fn event_times() -> (f64, f64) {
        let mut h = tight(&[]);
        h.run(10.0, 1e-2, &["regime"]).unwrap();
        (h.get("t_impact").unwrap(), h.get("t_release").unwrap())
    }

    /// The regimes follow 1, 2 (the instant t_impact), 3, 4; every sample before t_impact is
    /// regime 1, between t_impact and t_release regime 3, after it 4; the run ends at landing
    /// (fmi2Discard) with the logged reason, forward (+x), no misfire, after 2 s.
    #[test]
    fn regimes_run_in_order_and_the_projectile_lands_forward() {
        let mut h = tight(&[]);
        let traj = h.run(10.0, 1e-3, &["regime", "E_y"]).unwrap();
        let (t_i, t_r) = (h.get("t_impact").unwrap(), h.get("t_release").unwrap());
        assert!(0.0 < t_i && t_i < t_r, "t_impact {t_i}, t_release {t_r}");
        let mut seen = vec![1];
        for (k, &t) in traj.time.iter().enumerate() {
            let r = traj.get("regime")[k] as i32;
            let expected = if t < t_i {
                1
            } else if t < t_r {
                3
            } else {
                4
            };
            assert_eq!(r, expected, "regime at t = {t}");
            if r != *seen.last().unwrap() {
                if r == 3 {
                    seen.push(2);
                }
                seen.push(r);
            }
            if r < 4 {
                assert!(traj.get("E_y")[k] >= 0.0, "projectile below the ground on its cord at t = {t}");
            }
        }
        assert_eq!(seen, vec![1, 2, 3, 4]);
        let t_end = *traj.time.last().unwrap();
        assert!(t_end > 2.0 && t_end < 10.0, "landed at t = {t_end}");
        assert_eq!(h.get("misfire").unwrap(), 0.0);
        let range = h.get("range").unwrap();
        assert!(range > 0.0);
        assert!(h.messages().iter().any(|m| m.contains(&format!("the projectile landed at x = {range:.6} m"))), "{:?}", h.messages());
        eprintln!(
            "t_impact {t_i} t_release {t_r} landing {t_end} range {range} ideal {} efficiency {}",
            h.get("range_ideal").unwrap(),
            h.get("efficiency").unwrap()
        );
    }

    /// Total mechanical energy from the test's own kinematics (Snapshot) on a 1 ms grid: in
    /// regime 1 and in regime 3 it stays at its value at the start of the regime to a relative
    /// 1e-7 (rtol 1e-10 over ~1e3 solver steps accumulates ~1e-9); it agrees with the FMU's
    /// `energy` output to 1e-9 relative; and it does not increase across the impact.
    #[test]
    fn energy_is_conserved_while_falling_and_swinging_and_drops_at_the_impact() {
        let (t_i, t_r) = event_times();
        let mut h = tight(&[]);
        let e0 = snapshot(&mut h).energy();
        let mut e3: Option<f64> = None;
        let (mut drift1, mut drift3) = (0.0f64, 0.0f64);
        let mut e1_last = e0;
        let mut t = 0.0;
        while t + 1e-3 < t_r {
            h.step(1e-3).unwrap();
            t = h.instance.time();
            let s = snapshot(&mut h);
            let e = s.energy();
            assert!((e - h.get("energy").unwrap()).abs() < 1e-9 * e0, "energy output at t = {t}");
            if t < t_i {
                drift1 = drift1.max((e - e0).abs() / e0);
                e1_last = e;
            } else {
                let base = *e3.get_or_insert(e);
                drift3 = drift3.max((e - base).abs() / base);
            }
        }
        let e3 = e3.expect("samples in regime 3");
        eprintln!(
            "E0 {e0} J, regime 1 drift {drift1:e}, E after impact {e3} J, regime 3 drift {drift3:e}, impact loss {:e} J",
            e1_last - e3
        );
        assert!(drift1 < 1e-7 && drift3 < 1e-7, "drift {drift1:e} {drift3:e}");
        assert!(e3 <= e1_last * (1.0 + 1e-7), "the impact added energy: {e1_last} -> {e3}");
    }

    /// The three angular momenta (computed here from the point outputs and the rates) just
    /// before and just after the impact: each side is extrapolated linearly to t_impact from
    /// samples at 1 and 2 us (error ~ H'' (1e-6)^2, tiny), so gravity's finite-time impulse
    /// drops out; agreement to 1e-7 relative of |H_A| covers the 1e-10 s event location
    /// (|dH/dt| ~ 100 N m gives 1e-8) and rtol 1e-10.
    #[test]
    fn the_impact_conserves_the_three_angular_momenta() {
        let (t_i, _) = event_times();
        let delta = 1e-6;
        let mut h = tight(&[]);
        h.step(t_i - 2.0 * delta).unwrap();
        let b2 = snapshot(&mut h).momenta();
        h.step(delta).unwrap();
        let b1 = snapshot(&mut h).momenta();
        assert_eq!(h.get("regime").unwrap(), 1.0);
        h.step(2.0 * delta).unwrap();
        assert_eq!(h.get("regime").unwrap(), 3.0);
        let a1 = snapshot(&mut h).momenta();
        h.step(delta).unwrap();
        let a2 = snapshot(&mut h).momenta();
        let scale = b1[0].abs();
        for k in 0..3 {
            let before = 2.0 * b1[k] - b2[k];
            let after = 2.0 * a1[k] - a2[k];
            eprintln!("H[{k}] before {before} after {after} diff {:e}", after - before);
            assert!((after - before).abs() < 1e-7 * scale, "H[{k}]: {before} -> {after}");
        }
        // D leaves the ground after the impact.
        let s = snapshot(&mut h);
        assert!(s.d[1] > 0.0);
    }

    /// Flight: the first sample after release is taken back to t_release along the parabola;
    /// the closed-form landing x from that release state equals `range` to 1e-9 m (the event
    /// is located to 1e-10 s times |vx| ~ 10 m/s and rtol 1e-10 on an exact polynomial).
    /// Release happened where theta3 - theta2 = release_angle (to 1e-8 rad).
    #[test]
    fn the_landing_point_is_the_ballistic_range_from_the_release_state() {
        let (_, t_r) = event_times();
        let mut h = tight(&[]);
        h.step(t_r + 0.01).unwrap();
        assert_eq!(h.get("regime").unwrap(), 4.0);
        let rel = h.get("theta3").unwrap() - h.get("theta2").unwrap();
        assert!((rel - Trebuchet::default().release_angle).abs() < 1e-8, "{rel}");
        let tau = h.instance.time() - t_r;
        let (x, y, vx, vy) = (h.get("x_p").unwrap(), h.get("y_p").unwrap(), h.get("vx_p").unwrap(), h.get("vy_p").unwrap());
        // references.toml's ballistics (the ones tests/fmpy and tests/handbook evaluate too).
        let references = References::from_toml(include_str!("../references.toml")).expect("valid references");
        let sample = [("x", x), ("y", y), ("vx", vx), ("vy", vy), ("tau", tau), ("g", G)];
        let at = |name: &str| references.value(name, &sample).expect("a reference of the flight sample");
        let (x0, y0, vy0, t_f, expected) = (at("x_release"), at("y_release"), at("vy_release"), at("t_flight"), at("range"));
        let t_now = h.instance.time();
        h.step(10.0 - t_now).unwrap();
        let range = h.get("range").unwrap();
        eprintln!("release ({x0}, {y0}) v ({vx}, {vy0}); range {range} vs closed form {expected}");
        assert!((range - expected).abs() < 1e-9, "{range} vs {expected}");
        assert!((h.instance.time() - (t_r + t_f)).abs() < 1e-8);
    }

    /// A projectile of 5 lbf slows the whip so much that B reaches the ground while the
    /// projectile is still on its cord: `misfire`, the stop reason says so, no release, and
    /// B_y is 0 there (to 1e-9 m: 1e-10 s location times |v_B|).
    #[test]
    fn a_heavy_projectile_misfires() {
        let mut h = tight(&[("w_3", 5.0 * LBF)]);
        let traj = h.run(10.0, 1e-3, &["regime"]).unwrap();
        assert!(*traj.time.last().unwrap() < 10.0);
        assert_eq!(h.get("misfire").unwrap(), 1.0);
        assert_eq!(h.get("t_release").unwrap(), -1.0);
        assert_eq!(h.get("regime").unwrap(), 3.0);
        assert!(h.get("B_y").unwrap().abs() < 1e-9, "{}", h.get("B_y").unwrap());
        assert!(h.messages().iter().any(|m| m.contains("misfire: the counterweight B reached the ground")), "{:?}", h.messages());
    }

    /// The regime 3 mass-matrix EOM against Lagrange's equations applied numerically: L = T - V
    /// built from the body kinematics (`frame`, not the k_ij of derivation.md), d/dt(dL/dq') -
    /// dL/dq evaluated by nested central differences (step 2e-4) at an arbitrary state with the
    /// model's accelerations. The residual (N m) must vanish to 1e-5: truncation ~ eps^2 times
    /// third derivatives of L (~1e2 J) ~ 4e-6, round-off ~ 1e-16 |L| / eps^2 ~ 1e-7.
    #[test]
    fn swinging_equations_satisfy_lagrange_by_finite_differences() {
        let p = Trebuchet { regime: Regime::Swinging, pivot_x: -0.5, ..Default::default() };
        let x = [0.9, -0.4, 1.7, 1.3, -2.1, 4.0, 0.0, 0.0, 0.0, 0.0];
        let acc = p.swing_accelerations(&State::load(&x));
        let lag = |q: &[f64]| {
            let fr = p.frame(Regime::Swinging, &State::load(q));
            let m = p.inertia();
            let ke = 0.5 * m.m1 * fr.v_f.norm_squared()
                + 0.5 * m.i1 * q[3] * q[3]
                + 0.5 * m.m2 * fr.v_g.norm_squared()
                + 0.5 * m.i2 * q[4] * q[4]
                + 0.5 * m.m3 * fr.v_e.norm_squared();
            ke - p.g * (m.m1 * fr.f[1] + m.m2 * fr.g[1] + m.m3 * fr.e[1])
        };
        let eps = 2e-4;
        let d_dq = |q: &[f64], k: usize, f: &dyn Fn(&[f64]) -> f64| {
            let (mut qp, mut qm) = (q.to_vec(), q.to_vec());
            qp[k] += eps;
            qm[k] -= eps;
            (f(&qp) - f(&qm)) / (2.0 * eps)
        };
        for i in 0..3 {
            // d/dt of dL/dq'_i along (q', q''): chain rule with finite differences.
            let p_i = |q: &[f64]| d_dq(q, 3 + i, &lag);
            let mut ddt = 0.0;
            for j in 0..3 {
                ddt += d_dq(&x, j, &p_i) * x[3 + j] + d_dq(&x, 3 + j, &p_i) * acc[j];
            }
            let residual = ddt - d_dq(&x, i, &lag);
            eprintln!("equation {i}: d/dt dL/dq' = {ddt}, residual {residual:e}");
            assert!(residual.abs() < 1e-5, "equation {i}: residual {residual}");
        }
    }

    #[test]
    fn variable_table_is_well_formed() {
        let problems = fmu_export::table::Table::<Trebuchet>::new().problems();
        assert!(problems.is_empty(), "{problems:?}");
    }

    #[test]
    fn non_physical_parameters_are_refused_by_name() {
        for (name, value) in [("r_AC", 0.0), ("rho", -1.0), ("w_B", 0.0), ("g", 0.0), ("release_angle", 0.5)] {
            let mut h = Harness::<Trebuchet>::new();
            h.set(name, value).unwrap();
            let err = h.initialize(None).unwrap_err();
            assert!(err.contains(name), "{err}");
        }
    }

    /// MODELS.md's entry for this model is the one its variable table gives.
    #[test]
    fn catalogue_entry_is_current() {
        fmu_export::catalogue::check::<Trebuchet>(env!("CARGO_MANIFEST_DIR"));
    }

    /// The FMU's exact derivatives (dual numbers through the model's own equations) against
    /// central differences of its f64 equations, along the default run and at initialization
    /// (`check_derivatives` states the bound and why).
    #[test]
    fn exact_derivatives_match_central_differences() {
        let report = fmu_export::harness::check_derivatives::<Trebuchet>().unwrap();
        eprintln!("{report:?}");
        assert!(report.points > 10, "{report:?}");
    }
}
