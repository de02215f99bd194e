//! The FMI C interface shared by the export toolkit, the importer and the validator: the types,
//! status codes and function signatures of FMI 1.0 ([`fmi1`]), FMI 2.0 ([`fmi2`]) and FMI 3.0
//! ([`fmi3`]); the words
//! every side shares ([`FmiVersion`], [`Interface`], [`Status`]); (feature `symbols`) the one
//! table of each version's functions a loaded binary exports ([`fmi2::Functions`],
//! [`fmi3::Functions`], [`Library`], [`view!`]); and (feature `logger-shim`) the variadic
//! FMI 2.0 logger an importer hands to FMUs.

pub mod fmi1;
pub mod fmi2;
pub mod fmi3;
mod functions;

#[cfg(feature = "symbols")]
pub use functions::Library;

use std::ffi::c_int;
use std::fmt;

use serde::{Deserialize, Serialize};

/// An FMI version.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum FmiVersion {
    Fmi2,
    Fmi3,
    /// Last, so the serialized numbers of the others stay as they were.
    Fmi1,
}

/// An FMI interface: who integrates the model. Declared in the order of FMI 2.0's `fmi2Type`
/// (`fmi2ModelExchange` = 0, `fmi2CoSimulation` = 1), which is also the order serialized FMU
/// states of the export toolkit record.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum Interface {
    /// The importer integrates the FMU's derivatives.
    ModelExchange,
    /// The FMU integrates itself, one communication step at a time.
    CoSimulation,
}

impl Interface {
    /// Both, Co-Simulation first: the one an importer picks when an FMU offers both.
    pub const ALL: [Interface; 2] = [Interface::CoSimulation, Interface::ModelExchange];

    /// The command-line spelling: `co-simulation`, `model-exchange`.
    pub fn name(self) -> &'static str {
        match self {
            Interface::CoSimulation => "co-simulation",
            Interface::ModelExchange => "model-exchange",
        }
    }

    /// The interface for its command-line spelling.
    pub fn from_name(name: &str) -> Option<Interface> {
        Interface::ALL.into_iter().find(|i| i.name() == name.trim())
    }

    /// The standard's name, for messages: `Co-Simulation`, `Model Exchange` (also what
    /// `Display` prints).
    pub fn title(self) -> &'static str {
        match self {
            Interface::CoSimulation => "Co-Simulation",
            Interface::ModelExchange => "Model Exchange",
        }
    }

    /// `fmi2Type`, the interface as `fmi2Instantiate` takes it.
    pub fn fmi2_type(self) -> fmi2::Type {
        match self {
            Interface::ModelExchange => fmi2::MODEL_EXCHANGE,
            Interface::CoSimulation => fmi2::CO_SIMULATION,
        }
    }
}

impl fmt::Display for Interface {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.title())
    }
}

/// The status a function returns (`fmi2Status`, `fmi3Status`), numbered as the C enums number
/// it; FMI 3.0 has no `Pending`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[repr(i32)]
pub enum Status {
    Ok = 0,
    Warning = 1,
    Discard = 2,
    Error = 3,
    Fatal = 4,
    /// FMI 2.0 only: an asynchronous `fmi2DoStep` is still running.
    Pending = 5,
}

impl Status {
    /// The status for a C return value of `version`, `None` for a value it does not define.
    pub fn from_c(code: c_int, version: FmiVersion) -> Option<Status> {
        Some(match (code, version) {
            (0, _) => Status::Ok,
            (1, _) => Status::Warning,
            (2, _) => Status::Discard,
            (3, _) => Status::Error,
            (4, _) => Status::Fatal,
            (5, FmiVersion::Fmi2 | FmiVersion::Fmi1) => Status::Pending,
            _ => return None,
        })
    }

    /// The standard's name in `version` (`fmi2OK`, `fmi3Error`, ...).
    pub fn name(self, version: FmiVersion) -> &'static str {
        match (version, self) {
            (FmiVersion::Fmi2, Status::Ok) => "fmi2OK",
            (FmiVersion::Fmi2, Status::Warning) => "fmi2Warning",
            (FmiVersion::Fmi2, Status::Discard) => "fmi2Discard",
            (FmiVersion::Fmi2, Status::Error) => "fmi2Error",
            (FmiVersion::Fmi2, Status::Fatal) => "fmi2Fatal",
            (FmiVersion::Fmi2, Status::Pending) => "fmi2Pending",
            (FmiVersion::Fmi3, Status::Ok) => "fmi3OK",
            (FmiVersion::Fmi3, Status::Warning) => "fmi3Warning",
            (FmiVersion::Fmi3, Status::Discard) => "fmi3Discard",
            (FmiVersion::Fmi3, Status::Error) => "fmi3Error",
            (FmiVersion::Fmi3, Status::Fatal) => "fmi3Fatal",
            (FmiVersion::Fmi3, Status::Pending) => "fmi3Pending (not an FMI 3.0 status)",
            (FmiVersion::Fmi1, Status::Ok) => "fmiOK",
            (FmiVersion::Fmi1, Status::Warning) => "fmiWarning",
            (FmiVersion::Fmi1, Status::Discard) => "fmiDiscard",
            (FmiVersion::Fmi1, Status::Error) => "fmiError",
            (FmiVersion::Fmi1, Status::Fatal) => "fmiFatal",
            (FmiVersion::Fmi1, Status::Pending) => "fmiPending",
        }
    }
}

#[cfg(test)]
mod tests {
    /// FMI 1.0 has 39 functions, FMI 2.0 44, FMI 3.0 75: the name lists are what `runner
    /// validate` and the export tests check exports against, so a missing or doubled name
    /// matters.
    #[test]
    fn function_lists_are_complete_and_distinct() {
        let mut two: Vec<&str> = super::fmi2::COMMON_FUNCTIONS.to_vec();
        two.extend(super::fmi2::MODEL_EXCHANGE_FUNCTIONS);
        two.extend(super::fmi2::CO_SIMULATION_FUNCTIONS);
        let mut three: Vec<&str> = super::fmi3::COMMON_FUNCTIONS.to_vec();
        three.extend(super::fmi3::MODEL_EXCHANGE_FUNCTIONS);
        three.extend(super::fmi3::CO_SIMULATION_FUNCTIONS);
        three.extend(super::fmi3::SCHEDULED_EXECUTION_FUNCTIONS);
        // FMI 1.0: 10 functions of both interfaces, 14 of Model Exchange, 15 of Co-Simulation
        // (fmiModelFunctions.h, fmiFunctions.h).
        let mut one: Vec<&str> = super::fmi1::COMMON_FUNCTIONS.to_vec();
        one.extend(super::fmi1::MODEL_EXCHANGE_FUNCTIONS);
        one.extend(super::fmi1::CO_SIMULATION_FUNCTIONS);
        for (list, n) in [(&mut one, 39), (&mut two, 44), (&mut three, 75)] {
            list.sort();
            list.dedup();
            assert_eq!(list.len(), n);
        }
    }

    /// The statuses read back from their C values, by each version's rules.
    #[test]
    fn statuses_are_numbered_as_the_c_enums() {
        use super::{FmiVersion, Status};
        for (code, status) in [Status::Ok, Status::Warning, Status::Discard, Status::Error, Status::Fatal].into_iter().enumerate() {
            assert_eq!(status as i32, code as i32);
            assert_eq!(Status::from_c(code as i32, FmiVersion::Fmi3), Some(status));
        }
        assert_eq!(Status::from_c(5, FmiVersion::Fmi2), Some(Status::Pending));
        assert_eq!(Status::from_c(5, FmiVersion::Fmi3), None, "FMI 3.0 has no pending status");
        assert_eq!(super::fmi2::status_name(3), "fmi2Error");
        assert_eq!(super::fmi3::status_name(5), "an unknown fmi3Status");
        assert_eq!(super::fmi2::status_name(-1), "an unknown fmi2Status");
        assert_eq!((super::fmi1::status_name(3), super::fmi1::status_name(5)), ("fmiError", "fmiPending"));
    }

    #[test]
    fn interfaces_have_their_command_line_and_standard_names() {
        use super::Interface;
        for i in Interface::ALL {
            assert_eq!(Interface::from_name(i.name()), Some(i));
        }
        assert_eq!(Interface::ModelExchange.to_string(), "Model Exchange");
        assert_eq!(Interface::CoSimulation.fmi2_type(), super::fmi2::CO_SIMULATION);
        assert_eq!(Interface::from_name("me"), None);
    }

    /// Every name of a version's lists is a field of its table, and none is exported by a
    /// binary that exports nothing.
    #[cfg(feature = "symbols")]
    #[test]
    fn the_tables_know_every_name_of_their_lists() {
        use super::{fmi2, fmi3};
        let two: Vec<&str> =
            fmi2::COMMON_FUNCTIONS.iter().chain(&fmi2::MODEL_EXCHANGE_FUNCTIONS).chain(&fmi2::CO_SIMULATION_FUNCTIONS).copied().collect();
        assert!(two.iter().all(|name| !fmi2::Functions::MISSING.exports(name)));
        assert!(two.contains(&fmi2::Functions::NAMES.get_real_output_derivatives));
        let three = fmi3::COMMON_FUNCTIONS
            .iter()
            .chain(&fmi3::MODEL_EXCHANGE_FUNCTIONS)
            .chain(&fmi3::CO_SIMULATION_FUNCTIONS)
            .chain(&fmi3::SCHEDULED_EXECUTION_FUNCTIONS);
        assert_eq!(three.filter(|n| !fmi3::Functions::MISSING.exports(n)).count(), 75);
        assert_eq!(fmi3::Functions::NAMES.get_adjoint_derivative, "fmi3GetAdjointDerivative");
    }
}
