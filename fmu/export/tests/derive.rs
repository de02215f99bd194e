//! `#[derive(Variables)]` and `#[derive(StateVector)]` from outside the toolkit, as a model
//! crate uses them: the rows they generate, the ranges the toolkit checks from them (and
//! their messages), their min/max in modelDescription.xml, and the state vector's helpers.

use std::marker::PhantomData;

use fmi_schema::fmi2::VariableType;
use fmu_export::fmi2::describe::model_description;
use fmu_export::harness::Harness;
use fmu_export::model::{check_ranges, Access, Causality, Initial, Variability};
use fmu_export::table::Table;
use fmu_export::{Model, ModelError, ModelInfo, Range, StateVector, Variables};
use serde::{Deserialize, Serialize};

/// What a generic model's type parameter supplies (like the linkages' presets).
pub trait Flavour: Clone + std::fmt::Debug + Send + 'static {
    /// Whether the model has the optional parameter `extra`.
    const EXTRA: bool;
}

#[derive(Debug, Clone)]
pub struct With;
impl Flavour for With {
    const EXTRA: bool = true;
}

#[derive(Debug, Clone)]
pub struct Without;
impl Flavour for Without {
    const EXTRA: bool = false;
}

/// Position and velocity of a cart, and the reading of a gauge kept between them in the table.
#[derive(StateVector)]
pub struct Cart {
    /// Cart position
    #[state(unit = "m", display = "mm")]
    pub position: f64,
    /// Cart velocity
    /// (the second state)
    #[state(name = "v", unit = "m/s", after = "gauge")]
    pub velocity: f64,
}

/// A cart pushed by `push` against a spring `k`, with one variable of every kind.
#[derive(Debug, Clone, Serialize, Deserialize, Variables)]
#[serde(bound = "")]
#[variables(states = Cart, bound = "F: Flavour")]
pub struct Toy<F> {
    #[serde(skip)]
    pub flavour: PhantomData<fn() -> F>,
    /// Mass of the cart
    #[parameter(name = "M", unit = "kg", positive)]
    pub mass: f64,
    /// Spring stiffness
    #[parameter(unit = "N/m", non_negative)]
    pub k: f64,
    /// Initial position
    #[parameter(unit = "m", finite)]
    pub x0: f64,
    /// A fraction
    #[parameter(min = 0, max = 1)]
    pub fraction: f64,
    /// Only with the flavour that has it
    #[parameter(min = -2.5, when = F::EXTRA)]
    pub extra: f64,
    /// Plus or minus one
    #[parameter(one_of(1, -1))]
    pub sign: i32,
    /// A switch
    #[parameter]
    pub switch: bool,
    /// Force on the cart
    #[input(unit = "N", finite)]
    pub push: f64,
    /// Spring force
    #[output(unit = "N")]
    pub spring: f64,
    /// A gauge reading between the states
    #[output]
    pub gauge: f64,
    /// Last event time
    #[output(unit = "s", discrete)]
    pub t_event: f64,
    /// Count of something
    #[output]
    pub count: i32,
    /// Whether something holds
    #[output]
    pub holds: bool,
    /// Not a variable: no attribute.
    pub scratch: f64,
}

impl<F> Default for Toy<F> {
    fn default() -> Self {
        Toy {
            flavour: PhantomData,
            mass: 2.0,
            k: 10.0,
            x0: 0.5,
            fraction: 0.25,
            extra: 0.0,
            sign: 1,
            switch: false,
            push: 0.0,
            spring: 0.0,
            gauge: 0.0,
            t_event: -1.0,
            count: 0,
            holds: true,
            scratch: 0.0,
        }
    }
}

impl<F: Flavour> fmu_export::Equations<f64> for Toy<F> {
    fn initial_state(&mut self, x: &mut [f64]) -> Result<(), ModelError> {
        // A cross-parameter condition, checked after the declared ranges.
        if self.k == 0.0 && self.x0 != 0.0 {
            return Err(ModelError("parameters k = 0 and x0 != 0: nothing pulls the cart back".into()));
        }
        Cart { position: self.x0, velocity: 0.0 }.store(x);
        Ok(())
    }

    fn derivatives(&self, _t: f64, x: &[f64], dx: &mut [f64]) {
        let s = Cart::load(x);
        Cart { position: s.velocity, velocity: (self.push - self.k * s.position) / self.mass }.store(dx);
    }

    fn outputs(&mut self, _t: f64, x: &[f64]) {
        self.spring = self.k * Cart::load(x).position;
    }
}

impl<F: Flavour> Model for Toy<F> {
    const N_STATES: usize = Cart::LEN;

    fn info() -> ModelInfo {
        ModelInfo { identifier: "toy", description: "a cart", stop_time: 1.0, tolerance: 1e-6, output_interval: 0.1, documentation: "" }
    }
}

/// The generated rows in order: fields in declaration order, the unplaced state before the
/// first output, the placed one after the output it names, the optional row only when its
/// condition holds; names, descriptions (doc lines joined), kinds, units and ranges as declared.
#[test]
fn the_rows_are_the_fields_in_order_with_the_states_placed() {
    fn names<M>(rows: Vec<fmu_export::Variable<M>>) -> Vec<&'static str> {
        rows.iter().map(|r| r.name).collect()
    }
    assert_eq!(
        names(Toy::<With>::variables()),
        ["M", "k", "x0", "fraction", "extra", "sign", "switch", "push", "position", "spring", "gauge", "v", "t_event", "count", "holds"]
    );
    assert_eq!(
        names(Toy::<Without>::variables()),
        ["M", "k", "x0", "fraction", "sign", "switch", "push", "position", "spring", "gauge", "v", "t_event", "count", "holds"]
    );
    let rows = Toy::<With>::variables();
    let row = |name: &str| rows.iter().find(|r| r.name == name).unwrap();
    assert_eq!(row("M").description, "Mass of the cart");
    assert_eq!(row("v").description, "Cart velocity (the second state)");
    assert_eq!(
        (row("M").causality, row("M").variability, row("M").initial),
        (Causality::Parameter, Variability::Fixed, Some(Initial::Exact))
    );
    assert_eq!((row("M").unit, row("M").range), (Some("kg"), Range::Positive));
    assert_eq!(row("k").range, Range::NonNegative);
    assert_eq!(row("x0").range, Range::Finite);
    assert_eq!(row("fraction").range, Range::Bounds { min: Some(0.0), max: Some(1.0) });
    assert_eq!(row("extra").range, Range::Bounds { min: Some(-2.5), max: None });
    assert_eq!(row("sign").range, Range::OneOf(&[1, -1]));
    assert!(matches!(row("sign").access, Access::Integer { set: Some(_), .. }));
    assert!(matches!(row("switch").access, Access::Boolean { set: Some(_), .. }));
    assert_eq!((row("push").causality, row("push").variability), (Causality::Input, Variability::Continuous));
    assert_eq!((row("position").unit, row("position").display_unit), (Some("m"), Some("mm")));
    assert!(matches!(row("position").access, Access::State(0)) && matches!(row("v").access, Access::State(1)));
    assert_eq!((row("spring").causality, row("spring").variability), (Causality::Output, Variability::Continuous));
    assert!(matches!(row("spring").access, Access::Real { set: None, .. }));
    assert_eq!(row("t_event").variability, Variability::Discrete);
    assert!(matches!(row("count").access, Access::Integer { set: None, .. }) && row("count").variability == Variability::Discrete);
    assert!(matches!(row("holds").access, Access::Boolean { set: None, .. }));
    let problems = Table::<Toy<With>>::new().problems();
    assert!(problems.is_empty(), "{problems:?}");
}

/// The parameters by name with the model's values (not the defaults), Integers as f64, without
/// the Boolean, the input, the outputs and the solver controls.
#[test]
fn parameter_values_are_the_models_by_name() {
    let toy = Toy::<With> { k: 3.5, sign: -1, ..Toy::default() };
    let values = Table::<Toy<With>>::new().parameter_values(&toy);
    assert_eq!(values, [("M", 2.0), ("k", 3.5), ("x0", 0.5), ("fraction", 0.25), ("extra", 0.0), ("sign", -1.0)]);
}

/// The struct's layout, every field in order (variables or not), for the FMU-state tag.
#[test]
fn the_layout_lists_every_field_in_order() {
    assert!(Toy::<With>::LAYOUT.starts_with("flavour: PhantomData<fn()->F>; mass: f64; k: f64;"), "{}", Toy::<With>::LAYOUT);
    assert!(Toy::<With>::LAYOUT.ends_with("holds: bool; scratch: f64"), "{}", Toy::<With>::LAYOUT);
}

/// The state vector's index constants, length and load/store round trip.
#[test]
fn the_state_vector_loads_and_stores_by_name() {
    assert_eq!((Cart::POSITION, Cart::VELOCITY, Cart::LEN, <Cart as StateVector>::LEN), (0, 1, 2, 2));
    let mut x = [0.0; 2];
    Cart { position: 1.5, velocity: -2.0 }.store(&mut x);
    assert_eq!(x, [1.5, -2.0]);
    let s = Cart::load(&[3.0, 4.0]);
    assert_eq!((s.position, s.velocity), (3.0, 4.0));
}

/// Each declared range refuses what it should when initialization ends, with the require_*
/// helpers' message (and "input" for an input); the boundary values are accepted; the
/// cross-parameter check of initial_state runs only once the ranges pass.
#[test]
fn declared_ranges_are_checked_with_the_helpers_messages() {
    let refused = |params: &[(&str, f64)]| Harness::<Toy<With>>::started(params, None).err().unwrap_or_default();
    for (name, value, says) in [
        ("M", 0.0, "parameter M = 0 must be a finite number greater than zero"),
        ("M", -1.0, "parameter M = -1 must be a finite number greater than zero"),
        ("k", -0.5, "parameter k = -0.5 must be a finite number, zero or greater"),
        ("fraction", 1.5, "parameter fraction = 1.5 must be a finite number from 0 to 1"),
        ("fraction", -0.1, "parameter fraction = -0.1 must be a finite number from 0 to 1"),
        ("extra", -3.0, "parameter extra = -3 must be a finite number, -2.5 or greater"),
        ("sign", 0.0, "parameter sign = 0 must be +1 or -1"),
        ("sign", 2.0, "parameter sign = 2 must be +1 or -1"),
    ] {
        let err = refused(&[(name, value)]);
        assert!(err.contains(&format!("the parameters were refused: {says}")), "{name} = {value}: {err}");
    }
    for ok in [[("k", 0.0), ("x0", 0.0)], [("fraction", 0.0), ("extra", -2.5)], [("fraction", 1.0), ("sign", -1.0)]] {
        assert!(Harness::<Toy<With>>::started(&ok, None).is_ok(), "{ok:?}");
    }
    // In table order: M before k.
    assert!(refused(&[("k", -1.0), ("M", 0.0)]).contains("parameter M = 0"));
    // The model's own check only after the ranges.
    assert!(refused(&[("k", 0.0)]).contains("nothing pulls the cart back"));
    assert!(refused(&[("k", 0.0), ("M", 0.0)]).contains("parameter M = 0"));
    // Reals that are not finite never get that far: the set itself is refused.
    let mut h = Harness::<Toy<With>>::new();
    assert!(h.set("x0", f64::INFINITY).unwrap_err().contains("must be finite"));
}

/// The checks read the model's table, so a model changed directly (not through a set) is
/// checked too, and an input's message says input.
#[test]
fn an_input_range_names_an_input() {
    let toy = Toy::<With> { push: f64::NAN, ..Default::default() };
    assert_eq!(check_ranges(&toy).unwrap_err().0, "input push = NaN must be a finite number");
    assert!(check_ranges(&Toy::<With>::default()).is_ok());
}

/// modelDescription.xml carries the bounds FMI can say: min 0 for positive and non-negative
/// (FMI bounds are inclusive), both for min/max and one_of, none for finite; and the start
/// values lie inside them.
#[test]
fn ranges_appear_as_min_and_max_in_the_model_description() {
    let md = model_description::<Toy<With>>();
    let bounds = |name: &str| match &md.model_variables.iter().find(|v| v.name == name).unwrap().var_type {
        VariableType::Real(r) => (r.attributes.min, r.attributes.max),
        VariableType::Integer(i) => (i.attributes.min.map(f64::from), i.attributes.max.map(f64::from)),
        _ => panic!("{name}"),
    };
    assert_eq!(bounds("M"), (Some(0.0), None));
    assert_eq!(bounds("k"), (Some(0.0), None));
    assert_eq!(bounds("x0"), (None, None));
    assert_eq!(bounds("fraction"), (Some(0.0), Some(1.0)));
    assert_eq!(bounds("extra"), (Some(-2.5), None));
    assert_eq!(bounds("sign"), (Some(-1.0), Some(1.0)));
    assert_eq!(bounds("push"), (None, None));
    assert_eq!(md.check(), Vec::<String>::new());
    let xml = fmu_export::fmi2::describe::model_description_xml::<Toy<With>>().unwrap();
    assert!(xml.contains(r#"min="0""#), "{xml}");
}

/// A state placed after a name that is no variable is an authoring mistake, stopped loudly.
#[test]
#[should_panic(expected = "state 'x' is placed after 'nothing', which is no variable of the model")]
fn a_state_placed_after_an_unknown_name_is_refused() {
    let rows = vec![fmu_export::Variable::<()>::output("a", "a", |_| 0.0)];
    let states = vec![fmu_export::StateVariable { variable: fmu_export::Variable::state("x", "x", 0), after: Some("nothing") }];
    fmu_export::model::place_states(rows, 1, states);
}

/// A state that does not move.
#[derive(StateVector)]
pub struct Still {
    /// Position
    pub x: f64,
}

/// One model as two builds: the same table, but the second build's struct has one more field.
macro_rules! one_parameter_model {
    ($name:ident { $($extra:ident: $ty:ty),* }) => {
        #[derive(Debug, Clone, Default, Serialize, Deserialize, Variables)]
        #[variables(states = Still)]
        pub struct $name {
            /// A parameter
            #[parameter]
            pub p: f64,
            $(pub $extra: $ty,)*
        }
        impl fmu_export::Equations<f64> for $name {
            fn initial_state(&mut self, _x: &mut [f64]) -> Result<(), ModelError> {
                Ok(())
            }

            fn derivatives(&self, _t: f64, _x: &[f64], dx: &mut [f64]) {
                dx.fill(0.0);
            }
        }

        impl Model for $name {
            const N_STATES: usize = Still::LEN;
            fn info() -> ModelInfo {
                ModelInfo { identifier: "builds", description: "", stop_time: 1.0, tolerance: 1e-6, output_interval: 0.1, documentation: "" }
            }
        }
    };
}
one_parameter_model!(FirstBuild {});
one_parameter_model!(SecondBuild { cache: f64 });

/// Importers see the same GUID (the interface is the same), but an FMU state of the first
/// build is tagged apart from the second's: its bytes would not fit the second's struct.
#[test]
fn a_changed_struct_changes_the_fmu_state_tag_but_not_the_guid() {
    use fmu_export::table::{guid, guid_hash};
    assert_eq!(guid::<FirstBuild>(), guid::<SecondBuild>());
    assert_ne!(guid_hash::<FirstBuild>(), guid_hash::<SecondBuild>());
}
