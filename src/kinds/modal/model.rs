//! The model built from a scene: modal oscillators, modal loads, stops,
//! sensors and inputs as shape vectors. Plain numbers, ready for the solver.
//!
//! Internally modal coordinates are mass-normalised (`q'' + 2 zeta omega q'
//! + omega^2 q = f`, VSM12 eq. 13); `coordinate_scale` converts them to
//! the displacement units the interface shows.

use std::sync::Arc;

use nalgebra::{DMatrix, DVector};

use crate::contact::ModeTransfer;
use crate::kinds::modal::scene::{ActuatorKind, ContactMethod, TransferDamping, Load, Quantity, Scene, SceneError, Side, StructureSpec, SupportKind, Waveform};
use crate::contact::{Contact, Geometry, Law, PhaseTerm};
use crate::solve::lti::{CoupledSystem, LtiError, SystemCache};
use crate::solve::{ModalForcing, ModalState, Oscillator, C64};
use crate::structure::{tip_spring, Beam, Chain, Point, Structure, Support, TipSpringCantilever};

/// A stop acting on one point of the structure.
#[derive(Clone, Debug, PartialEq)]
pub struct StopModel {
    pub name: String,
    pub geometry: Geometry,
    pub law: Law,
}

/// A measuring point: displacement `w . q`, bending moment `m . q`.
#[derive(Clone, Debug, PartialEq)]
pub struct SensorModel {
    pub name: String,
    pub w: DVector<f64>,
    /// `EI W_j''(x)` when the bending moment is measured.
    pub moment: Option<DVector<f64>>,
}

/// Contact-phase decompositions a model hands the next one at most (the
/// newest): a scene's own active sets, without piling up those of a
/// sweep's earlier points (each a few `(2N)^2` matrices).
const HANDED_SYSTEMS: usize = 16;

/// What a model computed that holds for other scenes too, found by its
/// content: handed from a component's model to the next one when its
/// values change ([`crate::kind::Scene::shared`]).
#[derive(Clone, Debug, Default)]
pub struct Shared {
    pub phase_systems: SystemCache,
    pub beam: Option<Beam>,
}

impl Model {
    /// What a model built after this one can take over ([`Shared`]).
    pub fn shared(&self) -> Shared {
        let beam = match &self.structure {
            Structure::Beam(b) => Some(b.clone()),
            _ => None,
        };
        Shared { phase_systems: self.phase_systems.newest(HANDED_SYSTEMS), beam }
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct Model {
    pub structure: Structure,
    /// `q_mass_normalised = coordinate_scale * q_shown`.
    pub coordinate_scale: f64,
    pub oscillators: Vec<Oscillator>,
    /// Modal loads without the inputs.
    pub loads: ModalForcing,
    pub stops: Vec<StopModel>,
    pub sensors: Vec<SensorModel>,
    /// Modal load of a unit value of each input.
    pub inputs: Vec<DVector<f64>>,
    pub initial: ModalState,
    pub event_tolerance: f64,
    /// Relative tolerance of integrated (nonlinear) phases.
    pub integration_tolerance: f64,
    /// The fastest motion the scene's ranges admit (the interface's
    /// velocity limit): no state may start deeper inside a nonlinear stop
    /// than a point that fast reaches.
    pub speed_limit: f64,
    pub max_events_per_step: u64,
    /// Event-search points allowed within one call to advance (events included).
    pub max_probes_per_step: u64,
    /// Accumulate WB00's energy balance (FE_j, DE_j, impact losses).
    pub energy_balance: bool,
    /// Keep each stop's impulse (the scene outputs it); without it the
    /// impulses are not integrated and read 0.
    pub impulses: bool,
    /// Mode transfer (RMTM's MTM and RMTM methods) for the one tip stop that asks
    /// for it: the basis its contact phases use.
    pub transfer: Option<TransferBasis>,
    /// The contact phases' decompositions, shared by the model's clones.
    pub phase_systems: SystemCache,
}

/// The modes of the cantilever with the tip spring (the contact phase
/// of RMTM's mode transfer) and everything the model projects on them.
#[derive(Clone, Debug, PartialEq)]
pub struct TransferBasis {
    pub method: ContactMethod,
    /// The stop whose contact switches to this basis.
    pub stop: usize,
    pub oscillators: Vec<Oscillator>,
    /// Modal loads without the inputs, and each input's unit load.
    pub loads: ModalForcing,
    pub inputs: Vec<DVector<f64>>,
    /// `Phi_n(L)`: the stop's displacement is `Phi(L) . p`.
    pub stop_w: DVector<f64>,
    /// Each sensor's `Phi_n(x)` and `EI Phi_n''(x)`.
    pub sensors: Vec<(DVector<f64>, Option<DVector<f64>>)>,
    /// `T[n, j] = int mu Phi_n W_j dx`: spring coordinates of a field are
    /// `T q`, cantilever coordinates of a spring-mode field `T^T p`.
    pub overlap: DMatrix<f64>,
    /// The structure's damping projected on the contact modes, `T D T^T`
    /// (`transfer_damping: "inherited"`); `None`: modal damping.
    pub damping: Option<DMatrix<f64>>,
}

/// The modal loads of a scene on a basis: `shape_at` gives a point's shape
/// vector, `integral` the distributed load's `int W_j`, `inertial` the
/// load of a unit acceleration of the supports.
fn project_loads(scene: &Scene, shape_at: &dyn Fn(Point) -> DVector<f64>, integral: &DVector<f64>, inertial: &DVector<f64>) -> ModalForcing {
    let mut loads = ModalForcing::zero(integral.len());
    for load in &scene.loads {
        let (profile, amplitude, omega, waveform) = match load {
            Load::DistributedHarmonic { amplitude, omega, waveform, .. } => (integral.clone(), amplitude, omega, waveform),
            Load::PointHarmonic { x, mass, amplitude, omega, waveform, .. } => (shape_at(point(scene, *x, *mass)), amplitude, omega, waveform),
            Load::BaseExcitation { amplitude, omega, waveform, .. } => (inertial.clone(), amplitude, omega, waveform),
        };
        // A sin(W t) = Re(-i A e^{i W t}); A cos(W t) = Re(A e^{i W t}).
        let phase = match waveform {
            Waveform::Sin => C64::new(0.0, -1.0),
            Waveform::Cos => C64::new(1.0, 0.0),
        };
        loads.add_harmonic(*omega, profile.map(|p| phase * (amplitude * p)));
    }
    loads
}

fn project_inputs(scene: &Scene, shape_at: &dyn Fn(Point) -> DVector<f64>, inertial: &DVector<f64>) -> Vec<DVector<f64>> {
    scene
        .actuators
        .iter()
        .map(|a| match a.kind {
            ActuatorKind::Force => shape_at(point(scene, a.x, a.mass)),
            ActuatorKind::BaseAcceleration => inertial.clone(),
        })
        .collect()
}

impl TransferBasis {
    /// The spring-mode basis of a tip stop asking for mode transfer (the
    /// scene has validated: clamped-free beam, the stop at the tip).
    fn build(
        scene: &Scene,
        beam: &Beam,
        stop: usize,
        ModeTransfer { stiffness: k, method, damping }: ModeTransfer,
        zeta: &dyn Fn(usize) -> f64,
    ) -> TransferBasis {
        let n = beam.n_modes();
        let spring = TipSpringCantilever::new(n, beam.length, beam.mass_per_length, beam.bending_stiffness, k);
        let vector = |f: &dyn Fn(usize) -> f64| DVector::from_iterator(n, (1..=n).map(f));
        let shape_at = |p: Point| match p {
            Point::Along(x) => vector(&|j| spring.shape(j, x)),
            Point::Mass(_) => unreachable!("a beam"),
        };
        let integral = vector(&|j| spring.shape_integral(j));
        let inertial = vector(&|j| -beam.mass_per_length * spring.shape_integral(j));
        let overlap = tip_spring::overlap(&spring, beam);
        TransferBasis {
            method,
            stop,
            oscillators: (1..=n).map(|j| Oscillator::new(spring.omega(j), zeta(j))).collect(),
            loads: project_loads(scene, &shape_at, &integral, &inertial),
            inputs: project_inputs(scene, &shape_at, &inertial),
            // The tip value from the shear condition: accurate for stiff springs.
            stop_w: vector(&|j| spring.tip(j)),
            sensors: scene
                .sensors
                .iter()
                .map(|s| {
                    let x = s.x.expect("a beam's sensor has x");
                    let moment = s.quantities.contains(&Quantity::BendingMoment).then(|| vector(&|j| beam.bending_stiffness * spring.curvature(j, x)));
                    (vector(&|j| spring.shape(j, x)), moment)
                })
                .collect(),
            overlap: overlap.clone(),
            damping: (damping == TransferDamping::Inherited).then(|| {
                let d = DVector::from_iterator(n, (1..=n).map(|j| 2.0 * zeta(j) * beam.omega(j)));
                &overlap * DMatrix::from_diagonal(&d) * overlap.transpose()
            }),
        }
    }
}

fn point(scene: &Scene, x: Option<f64>, mass: Option<usize>) -> Point {
    match scene.structure {
        StructureSpec::Beam { .. } => Point::Along(x.expect("validated: beams use x")),
        StructureSpec::Chain { .. } => Point::Mass(mass.expect("validated: chains use mass")),
    }
}

impl Model {
    pub fn n_modes(&self) -> usize {
        self.oscillators.len()
    }

    /// Why runs of this model have no exact flow (for shooting), if they
    /// have none: a phase without a closed form, or a basis that changes.
    pub fn flow_unsupported(&self) -> Option<String> {
        if let Some(tr) = self.transfer.as_ref().filter(|tr| tr.method == crate::kinds::modal::scene::ContactMethod::Rmtm) {
            let s = &self.stops[tr.stop];
            return Some(format!(
                "stop '{}' (law '{}') uses mode transfer by RMTM, which has no periodic orbit: its frozen shape is kept in two truncated bases (the structure's modes and the tip-spring modes, T T^T != I), so where the structure's motion repeats, the contact phases' frozen load moves by the same amount every period (docs/mode_transfer.md); MTM and FIM have periodic orbits",
                s.name,
                s.law.name()
            ));
        }
        None
    }

    pub fn build(scene: &Scene) -> Result<Model, SceneError> {
        Self::build_with(scene, Shared::default())
    }

    /// [`Self::build`] with what `earlier` holds: the contact phases'
    /// decompositions (found by their matrices) and the beam's
    /// dimensionless modes (by support and number).
    pub fn build_with(scene: &Scene, earlier: Shared) -> Result<Model, SceneError> {
        let Shared { phase_systems, beam: earlier_beam } = earlier;
        scene.validate()?;
        let structure = match &scene.structure {
            StructureSpec::Beam { support, modes, .. } => {
                let section = scene.section()?.expect("a beam has a section");
                let support = match support {
                    SupportKind::PinnedPinned => Support::PinnedPinned,
                    SupportKind::ClampedFree => Support::ClampedFree,
                    SupportKind::ClampedClamped => Support::ClampedClamped,
                    SupportKind::ClampedPinned => Support::ClampedPinned,
                };
                Structure::Beam(Beam::new_with(support, *modes, section.length, section.mass_per_length, section.bending_stiffness, earlier_beam.as_ref()))
            }
            StructureSpec::Chain { masses, m, k, c } => Structure::Chain(Chain::new(*masses, *m, *k, *c)),
        };
        let n = structure.n_modes();
        let modes = 1..=n;
        let zeta = |j: usize| -> f64 {
            match (&structure, &scene.damping) {
                (Structure::Chain(c), _) => c.zeta(j),
                (Structure::Beam(b), Some(d)) => {
                    if let Some(z) = d.zeta {
                        z
                    } else if let Some(z) = &d.zeta_modes {
                        z[j - 1]
                    } else {
                        d.viscous.unwrap_or(0.0) / (2.0 * b.mass_per_length * b.omega(j))
                    }
                }
                (Structure::Beam(_), None) => 0.0,
            }
        };
        let oscillators: Vec<Oscillator> = modes.clone().map(|j| Oscillator::new(structure.omega(j), zeta(j))).collect();
        let vector = |f: &dyn Fn(usize) -> f64| DVector::from_iterator(n, modes.clone().map(f));
        let shape_at = |p: Point| vector(&|j| structure.shape(j, p));
        let inertial = vector(&|j| -structure.inertial_participation(j));
        let loads = match &structure {
            Structure::Beam(b) => project_loads(scene, &shape_at, &vector(&|j| b.shape_integral(j)), &inertial),
            Structure::Chain(_) => project_loads(scene, &shape_at, &DVector::zeros(n), &inertial),
        };
        let mut stops = Vec::new();
        for (i, s) in scene.stops.iter().enumerate() {
            let w = shape_at(point(scene, s.x, s.mass));
            if w.norm() < 1e-8 * w.len() as f64 {
                let field = match (s.x, s.mass) {
                    (Some(x), _) => format!("stops[{i}].x = {x}"),
                    (None, Some(m)) => format!("stops[{i}].mass = {m}"),
                    (None, None) => format!("stops[{i}]"),
                };
                return Err(SceneError(format!(
                    "{field}: every retained mode has a node there, so the stop cannot act; move it or keep more modes"
                )));
            }
            let law: Law = s.law.clone();
            let side = match s.side {
                Side::Positive => 1.0,
                Side::Negative => -1.0,
            };
            stops.push(StopModel { name: s.name.clone(), geometry: Geometry { w, gap: s.gap, side }, law });
        }
        let sensors = scene
            .sensors
            .iter()
            .map(|s| {
                let p = point(scene, s.x, s.mass);
                let moment = match (&structure, p) {
                    (Structure::Beam(b), Point::Along(x)) if s.quantities.contains(&Quantity::BendingMoment) => {
                        Some(vector(&|j| b.bending_stiffness * b.curvature(j, x)))
                    }
                    _ => None,
                };
                SensorModel { name: s.name.clone(), w: shape_at(p), moment }
            })
            .collect();
        let inputs = project_inputs(scene, &shape_at, &inertial);
        let mut transfer = None;
        for (i, s) in scene.stops.iter().enumerate() {
            if let (Some(spring), Structure::Beam(b)) = (s.law.mode_transfer(), &structure) {
                transfer = Some(TransferBasis::build(scene, b, i, spring, &zeta));
            }
        }
        let coordinate_scale = structure.coordinate_scale();
        let mut initial = ModalState::zeros(n);
        for (j, v) in scene.initial.q.iter().enumerate() {
            initial.q[j] = coordinate_scale * v;
        }
        for (j, v) in scene.initial.qd.iter().enumerate() {
            initial.qd[j] = coordinate_scale * v;
        }
        let model = Model {
            structure,
            coordinate_scale,
            oscillators,
            loads,
            stops,
            sensors,
            inputs,
            initial,
            event_tolerance: scene.solver.event_tolerance,
            integration_tolerance: crate::kinds::modal::scene::collocation_tolerance(scene.solver.integration_tolerance),
            speed_limit: crate::kinds::modal::interface::Limits::of(scene).velocity_range().max,
            max_events_per_step: scene.solver.max_events_per_step,
            max_probes_per_step: scene.solver.max_probes_per_step.unwrap_or_else(|| default_probe_budget(n)),
            energy_balance: scene.outputs.energy_balance,
            impulses: scene.outputs.impulse,
            transfer,
            phase_systems,
        };
        model.prepare_compliant_phases()?;
        Ok(model)
    }

    /// Decomposes, at build time, the phase of each linear compliant stop
    /// pressed alone: a scene with a spring stop is made to reach it, and
    /// its first contact then costs what every later one does. Sticking
    /// phases (rarer, and at many modes costlier) are decomposed when first
    /// reached.
    fn prepare_compliant_phases(&self) -> Result<(), SceneError> {
        let transfer_stop = self.transfer.as_ref().map(|tr| tr.stop);
        for (i, stop) in self.stops.iter().enumerate() {
            if Some(i) == transfer_stop || !matches!(stop.law.term(Contact::Pressed), PhaseTerm::Linear { .. }) {
                continue;
            }
            let mut key = vec![Contact::Open; self.stops.len()];
            key[i] = Contact::Pressed;
            self.phase_system(&key).map_err(|e| SceneError(format!("stops[{i}] ('{}'): the contact phase: {e}", stop.name)))?;
        }
        Ok(())
    }

    /// The coupled system of a contact phase given each stop's contact
    /// state: `K = diag(omega^2) + sum k w w^T`, `D = diag(2 zeta omega) +
    /// sum c w w^T` over pressed compliant stops, constrained by the held
    /// rigid ones; from the model's cache when decomposed before.
    pub fn phase_system(&self, key: &[Contact]) -> Result<Arc<CoupledSystem>, LtiError> {
        let n = self.n_modes();
        let mut k = DMatrix::from_diagonal(&DVector::from_iterator(n, self.oscillators.iter().map(|o| o.omega * o.omega)));
        let mut d = DMatrix::from_diagonal(&DVector::from_iterator(n, self.oscillators.iter().map(|o| 2.0 * o.a)));
        let mut cols: Vec<DVector<f64>> = Vec::new();
        for (stop, &contact) in self.stops.iter().zip(key) {
            let w = &stop.geometry.w;
            match stop.law.term(contact) {
                PhaseTerm::None => {}
                PhaseTerm::Constraint => cols.push(w.clone()),
                PhaseTerm::Linear { stiffness: ks, damping: c } => {
                    k.ger(ks, w, w, 1.0);
                    d.ger(c, w, w, 1.0);
                }
                PhaseTerm::Nonlinear => unreachable!("nonlinear phases are integrated, not coupled"),
            }
        }
        let w = if cols.is_empty() { DMatrix::zeros(n, 0) } else { DMatrix::from_columns(&cols) };
        self.phase_systems.get_or_build(k, d, w)
    }

    /// Kinetic plus strain energy `sum (qd_j^2 + omega_j^2 q_j^2) / 2`.
    pub fn energy(&self, state: &ModalState) -> f64 {
        self.oscillators
            .iter()
            .enumerate()
            .map(|(j, o)| 0.5 * (state.qd[j] * state.qd[j] + o.omega * o.omega * state.q[j] * state.q[j]))
            .sum()
    }

    /// Modal loads with the inputs added (held constant).
    pub fn forcing_with_inputs(&self, inputs: &[f64]) -> ModalForcing {
        let mut f = self.loads.clone();
        for (a, u) in self.inputs.iter().zip(inputs) {
            f.constant.axpy(*u, a, 1.0);
        }
        f
    }

    /// The shortest period of interest: the fundamental or the fastest load.
    pub fn shortest_period(&self) -> f64 {
        let mut w = self.oscillators.first().map(|o| o.omega).unwrap_or(1.0);
        for h in &self.loads.harmonics {
            w = w.max(h.omega);
        }
        2.0 * std::f64::consts::PI / w
    }
}

/// The default cap on the work of one communication step (event-search
/// points plus energy-balance nodes; an integrated phase's step counts as
/// [`INTEGRATED_STEP_WEIGHT`] points). One point costs about 0.06 N
/// microseconds on the development machine (N = 1 to 500), so the cap
/// keeps the worst step under a second at any number of modes, and a
/// whole horizon of every packaged scene, the Hertz stop's 1 s with about
/// 150 contacts among them, fits in one step (measured: `cargo run
/// --release --example probe_cost`, `cargo test --release --test
/// range_ends -- --nocapture`).
pub fn default_probe_budget(n_modes: usize) -> u64 {
    (8_000_000 / n_modes.max(1) as u64).min(4_000_000)
}

/// What one step of an integrated phase counts against the work cap, in
/// search points (every attempt: rejected ones, and those of the state at
/// a switch, too): a force-collocation step with its switch search costs
/// about as much as 5 to 8 of them (HertzStop at tolerance 1e-8: 9.8 us per
/// step against 1.3 us per point at N = 20, 49 us against 9 us at N = 160).
pub const INTEGRATED_STEP_WEIGHT: u64 = 8;
