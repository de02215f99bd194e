//! The derivatives an importer may ask for (see the [`Instance`](crate::frontend::Instance)
//! methods of the same names, where they are computed or refused).

use std::ffi::{c_int, c_void};
use std::panic::{catch_unwind, AssertUnwindSafe};

use super::variables::{get_arguments, set_arguments};
use super::{instance_mut, ok, slice, slice_mut, with_instance};
use crate::core::Failure;
use crate::frontend::{Call, Version};
use crate::logging::Status;
use crate::model::Model;

/// `GetDirectionalDerivative`, each array with its length (as [`get_sensitivity`]). The usual
/// call, a column of the Jacobian of the instance's point with the last call's unknowns, is
/// answered in place (the first at a new point computes the block): an importer makes it once
/// per state and input for every Jacobian. Anything else takes the general path (out of line),
/// which checks the call again and explains a refusal.
#[inline(always)]
pub unsafe fn get_directional_derivative<V: Version, M: Model>(
    c: *mut c_void,
    (unknowns, n_unknowns): (*const u32, usize),
    (knowns, n_knowns): (*const u32, usize),
    (seed, n_seed): (*const f64, usize),
    (sensitivity, n_sensitivity): (*mut f64, usize),
) -> c_int {
    if let Some(inst) = instance_mut::<V, M>(c) {
        // One of the four is null exactly when the lowest address is 0: three minima and a
        // test, where the four tests took 15 instructions (the compiler paired them in vectors).
        let lowest = (unknowns as usize).min(knowns as usize).min(seed as usize).min(sensitivity as usize);
        if lowest != 0 {
            let unknowns = std::slice::from_raw_parts(unknowns, n_unknowns);
            let knowns = std::slice::from_raw_parts(knowns, n_knowns);
            let seed = std::slice::from_raw_parts(seed, n_seed);
            let out = std::slice::from_raw_parts_mut(sensitivity, n_sensitivity);
            // The first column at a new point runs the model's equations. A panic there goes to
            // the general path, which runs them again and reports it (handling it here cost
            // every call 20 to 30 instructions).
            if let Ok(Some(true)) = catch_unwind(AssertUnwindSafe(|| inst.try_get_directional_derivative(unknowns, knowns, seed, out))) {
                return Status::Ok as c_int;
            }
        }
    }
    get_directional_derivative_in_full::<V, M>(c, (unknowns, n_unknowns), (knowns, n_knowns), (seed, n_seed), (sensitivity, n_sensitivity))
}

#[cold]
#[inline(never)]
unsafe fn get_directional_derivative_in_full<V: Version, M: Model>(
    c: *mut c_void,
    unknowns: (*const u32, usize),
    knowns: (*const u32, usize),
    seed: (*const f64, usize),
    sensitivity: (*mut f64, usize),
) -> c_int {
    get_sensitivity::<V, M>(c, Call::GetDirectionalDerivative, unknowns, knowns, seed, sensitivity)
}

/// `GetDirectionalDerivative` and FMI 3.0's `GetAdjointDerivative` (`call` says which): each
/// array with its length. A directional derivative's seed has one value per known and its
/// sensitivity one per unknown, an adjoint's the reverse (FMI 2.0 passes those numbers for the
/// lengths it does not have).
pub unsafe fn get_sensitivity<V: Version, M: Model>(
    c: *mut c_void,
    call: Call,
    (unknowns, n_unknowns): (*const u32, usize),
    (knowns, n_knowns): (*const u32, usize),
    (seed, n_seed): (*const f64, usize),
    (sensitivity, n_sensitivity): (*mut f64, usize),
) -> c_int {
    with_instance::<V, M>(c, call, |inst| {
        let w = V::WORDS;
        inst.trace(call, || format!("{}={n_unknowns}, {}={n_knowns}", w.n_unknowns, w.n_knowns));
        inst.check(call)?;
        let name = V::name(call);
        let adjoint = call == Call::GetAdjointDerivative;
        let (seeds, results) = if adjoint { (n_unknowns, n_knowns) } else { (n_knowns, n_unknowns) };
        if (n_seed, n_sensitivity) != (seeds, results) {
            return Err(Failure::error(format!(
                "{name}: nSeed = {n_seed} and nSensitivity = {n_sensitivity}, but the {n_unknowns} unknowns and {n_knowns} knowns are scalars: {seeds} seed values and {results} sensitivities"
            )));
        }
        let unknowns = slice(unknowns, n_unknowns, name, w.unknowns)?;
        let knowns = slice(knowns, n_knowns, name, w.knowns)?;
        let seed = slice(seed, n_seed, name, w.seed)?;
        let sensitivity = slice_mut(sensitivity, n_sensitivity, name, w.sensitivity)?;
        ok(if adjoint {
            inst.get_adjoint_derivative(unknowns, knowns, seed, sensitivity)
        } else {
            inst.get_directional_derivative(unknowns, knowns, seed, sensitivity)
        })
    })
}

/// `fmi2GetRealOutputDerivatives`, `fmi3GetOutputDerivatives` (FMI 2.0 passes `n` for
/// `n_values`). The usual call, the last call's request again (a master's at every
/// communication point), is answered in place; anything else, and any problem, takes the
/// general path (out of line), which checks the call again and explains a refusal.
#[inline(always)]
pub unsafe fn get_output_derivatives<V: Version, M: Model>(
    c: *mut c_void,
    vr: *const u32,
    n: usize,
    orders: *const i32,
    values: *mut f64,
    n_values: usize,
) -> c_int {
    if n_values == n && !vr.is_null() && !orders.is_null() && !values.is_null() {
        if let Some(inst) = instance_mut::<V, M>(c) {
            // SAFETY: FMI's contract: vr and orders point at n entries, values at n_values (= n).
            let (vrs, orders) = (std::slice::from_raw_parts(vr, n), std::slice::from_raw_parts(orders, n));
            let out = std::slice::from_raw_parts_mut(values, n);
            // The model's equations run here: a panic goes to the general path, which runs them
            // again and reports it.
            if let Ok(Some(true)) = catch_unwind(AssertUnwindSafe(|| inst.try_get_output_derivatives(vrs, orders, out))) {
                return Status::Ok as c_int;
            }
        }
    }
    get_output_derivatives_in_full::<V, M>(c, vr, n, orders, values, n_values)
}

#[cold]
#[inline(never)]
unsafe fn get_output_derivatives_in_full<V: Version, M: Model>(
    c: *mut c_void,
    vr: *const u32,
    n: usize,
    orders: *const i32,
    values: *mut f64,
    n_values: usize,
) -> c_int {
    let call = Call::GetOutputDerivatives;
    with_instance::<V, M>(c, call, |inst| {
        let (vrs, values) = get_arguments::<V, M, f64>(inst, call, vr, n, values, n_values)?;
        let orders = slice(orders, n, V::name(call), "order[]")?;
        ok(inst.get_output_derivatives(vrs, orders, values))
    })
}

/// `fmi2SetRealInputDerivatives`. The usual call, the last call's inputs and orders with new
/// values (a master's at every communication point), is answered in place; anything else, and
/// any problem, takes the general path (out of line), which checks the call again and explains
/// a refusal.
#[inline(always)]
pub unsafe fn set_input_derivatives<V: Version, M: Model>(
    c: *mut c_void,
    vr: *const u32,
    n: usize,
    orders: *const i32,
    values: *const f64,
) -> c_int {
    if !vr.is_null() && !orders.is_null() && !values.is_null() {
        if let Some(inst) = instance_mut::<V, M>(c) {
            // SAFETY: FMI's contract: each array has n entries.
            let (vrs, orders, values) =
                (std::slice::from_raw_parts(vr, n), std::slice::from_raw_parts(orders, n), std::slice::from_raw_parts(values, n));
            // No model code runs here (the table's setters and getters of the inputs' fields).
            if let Ok(true) = catch_unwind(AssertUnwindSafe(|| inst.try_set_input_derivatives(vrs, orders, values))) {
                return Status::Ok as c_int;
            }
        }
    }
    set_input_derivatives_in_full::<V, M>(c, vr, n, orders, values)
}

#[cold]
#[inline(never)]
unsafe fn set_input_derivatives_in_full<V: Version, M: Model>(
    c: *mut c_void,
    vr: *const u32,
    n: usize,
    orders: *const i32,
    values: *const f64,
) -> c_int {
    let call = Call::SetInputDerivatives;
    with_instance::<V, M>(c, call, |inst| {
        let (vrs, values) = set_arguments::<V, M, f64>(inst, call, vr, n, values, n)?;
        let orders = slice(orders, n, V::name(call), "order[]")?;
        ok(inst.set_input_derivatives(vrs, orders, values))
    })
}

#[cfg(test)]
mod tests {
    use std::sync::{Arc, Mutex};

    use super::*;
    use crate::core::derivatives::tests::Decay;
    use crate::fmi3::Fmi3;
    use crate::frontend::ffi::{instantiate, set_continuous_states, simple, Request};
    use crate::frontend::{Interface, Setup};
    use crate::logging::Logger;
    use crate::table::Table;

    /// An FMI 3.0 Model Exchange instance of `Decay` (x' = -k x + u, y = x^2 + u; k = 2,
    /// u = 0.5) in Continuous-Time Mode at x = 1.5, through the C functions' generic bodies,
    /// its log lines collected.
    unsafe fn continuous() -> (*mut c_void, Arc<Mutex<Vec<String>>>) {
        continuous_of::<Decay>(1.5)
    }

    /// A logger that collects the instance's log lines, and the lines.
    fn collected_log() -> (Logger, Arc<Mutex<Vec<String>>>) {
        let log = Arc::new(Mutex::new(Vec::new()));
        let sink = log.clone();
        (Logger::new(Some(Box::new(move |_, _, m: &str| sink.lock().expect("log lock").push(m.to_owned()))), false), log)
    }

    /// An instance of model `M` through FMI version `V`'s generic `call` (an instantiation
    /// function) for `interface`, its log lines collected.
    unsafe fn instance<V: Version, M: Model>(call: &'static str, interface: Interface) -> (*mut c_void, Arc<Mutex<Vec<String>>>) {
        let (logger, log) = collected_log();
        let token = crate::table::guid::<M>();
        let c = instantiate::<V, M>(|| {
            Some(Request { call, logger, name: Some("decay"), setup: Ok(Setup::plain(interface)), token: Some(token), resources: None })
        });
        assert!(!c.is_null());
        (c, log)
    }

    /// [`continuous`] for model `M` at state `x`.
    unsafe fn continuous_of<M: Model>(x: f64) -> (*mut c_void, Arc<Mutex<Vec<String>>>) {
        let (c, log) = instance::<Fmi3, M>("fmi3InstantiateModelExchange", Interface::ModelExchange);
        assert_eq!(simple::<Fmi3, M>(c, Call::EnterInitializationMode, |i| i.enter_initialization_mode_with(None, 0.0, None)), 0);
        assert_eq!(simple::<Fmi3, M>(c, Call::ExitInitializationMode, |i| i.exit_initialization_mode()), 0);
        assert_eq!(simple::<Fmi3, M>(c, Call::EnterContinuousTimeMode, |i| i.enter_continuous_time_mode()), 0);
        assert_eq!(set_continuous_states::<Fmi3, M>(c, [x].as_ptr(), 1), 0);
        (c, log)
    }

    /// How often `Fragile`'s equations panicked.
    static PANICS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

    /// x' = -k x, whose equations panic beyond x = 10: a model bug only some states reach.
    #[derive(Debug, Clone, serde::Serialize, serde::Deserialize, crate::Variables)]
    #[variables(states = FragileState)]
    struct Fragile<T = f64> {
        /// Rate constant
        #[parameter]
        k: T,
    }

    #[derive(crate::StateVector)]
    struct FragileState<T = f64> {
        /// The state
        x: T,
    }

    impl Default for Fragile {
        fn default() -> Self {
            Fragile { k: 1.0 }
        }
    }

    impl<T: crate::Scalar> crate::model::Equations<T> for Fragile<T> {
        fn initial_state(&mut self, x: &mut [T]) -> Result<(), crate::model::ModelError> {
            FragileState { x: T::from(1.0) }.store(x);
            Ok(())
        }

        fn derivatives(&self, _t: T, x: &[T], dx: &mut [T]) {
            let FragileState { x } = FragileState::load(x);
            if x.value() > 10.0 {
                PANICS.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
                panic!("model bug at x = {}", x.value());
            }
            FragileState { x: -self.k * x }.store(dx);
        }
    }

    impl Model for Fragile {
        const N_STATES: usize = 1;

        fn info() -> crate::model::ModelInfo {
            crate::model::ModelInfo {
                identifier: "fragile",
                description: "",
                stop_time: 1.0,
                tolerance: 1e-6,
                output_interval: 0.1,
                documentation: "",
            }
        }
    }

    /// The first column at a new point runs the model's equations on the in-place route: a
    /// panic there does not unwind into the importer but is the call's fmi3Error with the
    /// general path's log line (the general path runs the equations again: twice in all).
    #[test]
    fn a_panic_computing_a_column_in_place_is_the_calls_error() {
        unsafe {
            let (c, log) = continuous_of::<Fragile>(1.0);
            let table = Table::<Fragile>::new();
            let vr = |name: &str| table.rows.iter().position(|r| r.name == name).unwrap() as u32;
            let (der, x) = (vr("der(x)"), vr("x"));
            let mut out = [f64::NAN];
            let mut column = |c| {
                let status = get_directional_derivative::<Fmi3, Fragile>(c, (&der, 1), (&x, 1), ([1.0].as_ptr(), 1), (out.as_mut_ptr(), 1));
                (status, out[0])
            };
            assert_eq!(column(c), (0, -1.0), "the full path: d x'/dx = -k");
            assert_eq!(set_continuous_states::<Fmi3, Fragile>(c, [20.0].as_ptr(), 1), 0);
            assert_eq!(column(c).0, Status::Error as c_int, "the in-place route at a new point, which panics");
            assert_eq!(PANICS.load(std::sync::atomic::Ordering::SeqCst), 2, "in place, then on the general path");
            let lines = log.lock().unwrap().clone();
            assert!(
                lines.len() == 1
                    && lines[0].contains("fmi3GetDirectionalDerivative: internal error in the model code (model bug at x = 20)"),
                "{lines:?}"
            );
            crate::frontend::ffi::free_instance::<Fmi3, Fragile>(c);
        }
    }

    fn vr(name: &str) -> u32 {
        Table::<Decay>::new().rows.iter().position(|r| r.name == name).unwrap_or_else(|| panic!("{name}")) as u32
    }

    /// `fmi3GetDirectionalDerivative` of `unknowns` for the one known `known` (seed 1): the
    /// status and the sensitivities.
    unsafe fn column(c: *mut c_void, unknowns: &[u32], known: u32) -> (c_int, Vec<f64>) {
        let mut out = vec![f64::NAN; unknowns.len()];
        let status = get_directional_derivative::<Fmi3, Decay>(
            c,
            (unknowns.as_ptr(), unknowns.len()),
            (&known, 1),
            ([1.0].as_ptr(), 1),
            (out.as_mut_ptr(), out.len()),
        );
        (status, out)
    }

    /// The usual call, answered in place from the Jacobian of the point, gives what the full
    /// path gives (the first call at a point computes it), follows the point when the states
    /// move, and refuses as strictly: a known or unknown not of the mode, lengths that do not
    /// match and a state that does not allow the call are fmi3Error with a log line, however
    /// warm the cache; and with logCalls on the call is still traced. The values are exact (the
    /// equations are polynomials): d der(x)/dx = -k, dy/dx = 2 x, d der(x)/du = dy/du = 1.
    #[test]
    fn a_column_at_the_same_point_is_answered_in_place_and_refusals_stay() {
        unsafe {
            let (c, log) = continuous();
            let (der, y, x, u, k) = (vr("der(x)"), vr("y"), vr("x"), vr("u"), vr("k"));
            let error = Status::Error as c_int;
            assert_eq!(column(c, &[der, y], x), (0, vec![-2.0, 3.0]), "the full path, which computes the Jacobian");
            assert_eq!(column(c, &[der, y], x), (0, vec![-2.0, 3.0]), "in place");
            assert_eq!(column(c, &[der, y], u), (0, vec![1.0, 1.0]), "in place, another column");
            assert_eq!(set_continuous_states::<Fmi3, Decay>(c, [2.0].as_ptr(), 1), 0);
            assert_eq!(column(c, &[der, y], x), (0, vec![-2.0, 4.0]), "a new point: computed again");
            assert!(log.lock().unwrap().is_empty(), "{:?}", log.lock().unwrap());

            assert_eq!(column(c, &[der, y], k).0, error, "a parameter is not a known in Continuous-Time Mode");
            assert_eq!(column(c, &[der, y], 999).0, error);
            assert_eq!(column(c, &[der, k], x).0, error, "a parameter is not an unknown");
            let mut short = [0.0];
            let status =
                get_directional_derivative::<Fmi3, Decay>(c, ([der, y].as_ptr(), 2), (&x, 1), ([1.0].as_ptr(), 1), (short.as_mut_ptr(), 1));
            assert_eq!(status, error, "one sensitivity for two unknowns");
            let lines = log.lock().unwrap().clone();
            assert_eq!(lines.len(), 4, "{lines:?}");
            assert!(
                lines[0].starts_with("fmi3GetDirectionalDerivative: 'k' (value reference") && lines[0].contains("is not a known"),
                "{lines:?}"
            );
            assert!(lines[1].contains("value reference 999 is not a variable of this FMU"), "{lines:?}");
            assert!(lines[2].contains("'k'") && lines[2].contains("is not an unknown"), "{lines:?}");
            assert!(lines[3].contains("nSensitivity = 1"), "{lines:?}");

            // The cache is warm again, and the call still traced under logCalls.
            assert_eq!(column(c, &[der, y], x), (0, vec![-2.0, 4.0]));
            assert_eq!(simple::<Fmi3, Decay>(c, Call::SetDebugLogging, |i| i.set_debug_logging(true, &["logCalls"])), 0);
            log.lock().unwrap().clear();
            assert_eq!(column(c, &[der, y], x), (0, vec![-2.0, 4.0]));
            assert_eq!(log.lock().unwrap().clone(), ["fmi3GetDirectionalDerivative(nUnknowns=2, nKnowns=1)"]);
            assert_eq!(simple::<Fmi3, Decay>(c, Call::SetDebugLogging, |i| i.set_debug_logging(false, &[])), 0);

            // After a reset the instance is in Instantiated, where the call is not allowed.
            assert_eq!(simple::<Fmi3, Decay>(c, Call::Reset, |i| i.reset()), 0);
            log.lock().unwrap().clear();
            assert_eq!(column(c, &[der, y], x).0, error);
            let lines = log.lock().unwrap().clone();
            assert!(lines.len() == 1 && lines[0].contains("not allowed in state Instantiated"), "{lines:?}");
            crate::frontend::ffi::free_instance::<Fmi3, Decay>(c);
        }
    }

    /// An FMI 2.0 Co-Simulation instance of `Decay` (k = 2, u = 0.5, x0 = 3) after
    /// initialization at t = 0, through the C functions' generic bodies, its log lines
    /// collected.
    unsafe fn stepping() -> (*mut c_void, Arc<Mutex<Vec<String>>>) {
        use crate::fmi2::Fmi2;
        let (c, log) = instance::<Fmi2, Decay>("fmi2Instantiate", Interface::CoSimulation);
        assert_eq!(simple::<Fmi2, Decay>(c, Call::SetupExperiment, |i| i.setup_experiment(Some(1e-10), 0.0, None)), 0);
        assert_eq!(simple::<Fmi2, Decay>(c, Call::EnterInitializationMode, |i| i.enter_initialization_mode()), 0);
        assert_eq!(simple::<Fmi2, Decay>(c, Call::ExitInitializationMode, |i| i.exit_initialization_mode()), 0);
        (c, log)
    }

    /// A master's requests, the same at every communication point, are answered in place and
    /// give what the general path gives (the first call takes it); a request that is not the
    /// last one, a non-finite input derivative and a state that does not allow the call are
    /// still refused by name however often the request was made; under logCalls the general
    /// path answers alike. The values are those by hand (the core's test): at x = 3, u = 0.5
    /// held, x' = -5.5, y' = 2 x x' = -33; driven by u' = 0.25, u'' = 0.5, u''' = -1,
    /// x'' = 11.25, y' = -32.75.
    #[test]
    fn repeated_output_and_input_derivative_requests_are_answered_in_place_and_refusals_stay() {
        use crate::fmi2::Fmi2;
        unsafe {
            let (c, log) = stepping();
            let (x, y, u) = (vr("x"), vr("y"), vr("u"));
            let error = Status::Error as c_int;
            let rates = |c, vrs: &[u32], orders: &[i32]| {
                let mut out = vec![f64::NAN; vrs.len()];
                let status =
                    get_output_derivatives::<Fmi2, Decay>(c, vrs.as_ptr(), vrs.len(), orders.as_ptr(), out.as_mut_ptr(), vrs.len());
                (status, out)
            };
            let set = |c, orders: &[i32], values: &[f64]| {
                let vrs = vec![u; orders.len()];
                set_input_derivatives::<Fmi2, Decay>(c, vrs.as_ptr(), vrs.len(), orders.as_ptr(), values.as_ptr())
            };
            assert_eq!(rates(c, &[x, y], &[1, 1]), (0, vec![-5.5, -33.0]), "the general path, which keeps the request");
            assert_eq!(rates(c, &[x, y], &[1, 1]), (0, vec![-5.5, -33.0]), "in place");
            assert_eq!(set(c, &[1, 2, 3], &[0.25, 0.5, -1.0]), 0, "the general path");
            assert_eq!(set(c, &[1, 2, 3], &[0.25, 0.5, -1.0]), 0, "in place");
            assert_eq!(rates(c, &[x, y, x], &[1, 1, 2]), (0, vec![-5.5, -32.75, 11.25]), "a new request: the general path");
            assert_eq!(rates(c, &[x, y, x], &[1, 1, 2]), (0, vec![-5.5, -32.75, 11.25]), "in place");
            // Both in place, the new input derivatives seen: u' = 0.5 gives y' = -32.5, x'' = 11.5.
            assert_eq!(set(c, &[1, 2, 3], &[0.5, 1.0, -1.0]), 0);
            assert_eq!(rates(c, &[x, y, x], &[1, 1, 2]), (0, vec![-5.5, -32.5, 11.5]), "in place, the new polynomial");
            // One output's three orders (a polynomial master's request, served as an array in
            // place): what the general path gave for it.
            let general = rates(c, &[y, y, y], &[1, 2, 3]);
            assert_eq!(general.0, 0, "a new request: the general path");
            assert_eq!(rates(c, &[y, y, y], &[1, 2, 3]), general, "in place");
            // Zero derivatives set in place: u held again, x'' = -k x' = 11, y' = 2 x x' = -33.
            assert_eq!(set(c, &[1, 2, 3], &[0.0, 0.0, 0.0]), 0);
            assert_eq!(rates(c, &[x, y, x], &[1, 1, 2]), (0, vec![-5.5, -33.0, 11.0]), "u held");
            assert_eq!(set(c, &[1, 2, 3], &[0.5, 1.0, -1.0]), 0);
            // One output's first derivative (a Gauss-Seidel master's request), also served in place.
            assert_eq!(rates(c, &[x], &[1]), (0, vec![-5.5]), "a new request: the general path");
            assert_eq!(rates(c, &[x], &[1]), (0, vec![-5.5]), "in place");
            let lines = log.lock().unwrap().clone();
            assert!(lines.is_empty(), "{lines:?}");

            assert_eq!(set(c, &[1, 2, 3], &[0.25, f64::NAN, -1.0]), error, "the kept request with a NaN");
            assert_eq!(rates(c, &[x, y, x], &[1, 1, 4]).0, error, "order 4");
            assert_eq!(rates(c, &[x, u, x], &[1, 1, 2]).0, error, "an input has no output derivatives");
            let lines = log.lock().unwrap().clone();
            assert_eq!(lines.len(), 3, "{lines:?}");
            assert!(lines[0].contains("derivative 2 of 'u' = NaN refused"), "{lines:?}");
            assert!(lines[1].contains("order 4 of 'x' refused"), "{lines:?}");
            assert!(lines[2].contains("'u' (value reference") && lines[2].contains("not a Real output"), "{lines:?}");

            // Under logCalls the general path answers, with the same values.
            assert_eq!(simple::<Fmi2, Decay>(c, Call::SetDebugLogging, |i| i.set_debug_logging(true, &["logCalls"])), 0);
            assert_eq!(rates(c, &[x, y, x], &[1, 1, 2]), (0, vec![-5.5, -32.5, 11.5]), "the refused NaN changed nothing");
            assert_eq!(set(c, &[1, 2, 3], &[0.25, 0.5, -1.0]), 0);
            assert_eq!(simple::<Fmi2, Decay>(c, Call::SetDebugLogging, |i| i.set_debug_logging(false, &[])), 0);

            // After a reset the instance is in Instantiated, where output derivatives are not
            // allowed.
            assert_eq!(simple::<Fmi2, Decay>(c, Call::Reset, |i| i.reset()), 0);
            log.lock().unwrap().clear();
            assert_eq!(rates(c, &[x, y, x], &[1, 1, 2]).0, error);
            let lines = log.lock().unwrap().clone();
            assert!(lines.len() == 1 && lines[0].contains("fmi2GetRealOutputDerivatives"), "{lines:?}");
            crate::frontend::ffi::free_instance::<Fmi2, Decay>(c);
        }
    }
}
