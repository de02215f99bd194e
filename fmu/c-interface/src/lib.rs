//! The FMI C interface shared by the export toolkit and the importer: the types, status codes
//! and function signatures of FMI 2.0 ([`fmi2`]) and FMI 3.0 ([`fmi3`]), and (feature
//! `logger-shim`) the variadic FMI 2.0 logger an importer hands to FMUs.

pub mod fmi2;
pub mod fmi3;

#[cfg(test)]
mod tests {
    /// FMI 2.0 has 44 functions, FMI 3.0 75: the name lists are what `runner validate` and
    /// the export tests check exports against, so a missing or doubled name matters.
    #[test]
    fn function_lists_are_complete_and_distinct() {
        let mut two: Vec<&str> = super::fmi2::COMMON_FUNCTIONS.to_vec();
        two.extend(super::fmi2::MODEL_EXCHANGE_FUNCTIONS);
        two.extend(super::fmi2::CO_SIMULATION_FUNCTIONS);
        let mut three: Vec<&str> = super::fmi3::COMMON_FUNCTIONS.to_vec();
        three.extend(super::fmi3::MODEL_EXCHANGE_FUNCTIONS);
        three.extend(super::fmi3::CO_SIMULATION_FUNCTIONS);
        three.extend(super::fmi3::SCHEDULED_EXECUTION_FUNCTIONS);
        for (list, n) in [(&mut two, 44), (&mut three, 75)] {
            list.sort();
            list.dedup();
            assert_eq!(list.len(), n);
        }
    }
}
