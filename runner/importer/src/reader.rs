//! Reading a fixed list of variables at every communication point: one get call per type,
//! into buffers made once, and one number per array element for the caller (Booleans as 0/1).
//! Every value is also available exactly, as text, for result files (String, Binary, and
//! integers too wide for an f64).

use crate::model::{FmiVersion, Kind, Variable};
use crate::number_text;

/// The values of one type, as the FMI functions of the FMU's version fill them.
#[derive(Debug, Clone)]
pub(crate) enum Buffer {
    F64(Vec<f64>),
    F32(Vec<f32>),
    I8(Vec<i8>),
    U8(Vec<u8>),
    I16(Vec<i16>),
    U16(Vec<u16>),
    I32(Vec<i32>),
    U32(Vec<u32>),
    I64(Vec<i64>),
    U64(Vec<u64>),
    /// FMI 2.0 `fmi2Boolean` (a C int).
    IntBool(Vec<i32>),
    /// FMI 3.0 `fmi3Boolean` (a C bool).
    Bool(Vec<bool>),
    /// FMI 1.0 `fmiBoolean` (a C char).
    CharBool(Vec<std::ffi::c_char>),
    /// Strings, copied out of the FMU's memory at each read.
    Text(Vec<String>),
    /// Binary values, copied out at each read.
    Bytes(Vec<Vec<u8>>),
}

impl Buffer {
    fn new(kind: Kind, version: FmiVersion, n: usize) -> Buffer {
        match kind {
            Kind::Real => Buffer::F64(vec![0.0; n]),
            Kind::Float32 => Buffer::F32(vec![0.0; n]),
            Kind::Int8 => Buffer::I8(vec![0; n]),
            Kind::UInt8 => Buffer::U8(vec![0; n]),
            Kind::Int16 => Buffer::I16(vec![0; n]),
            Kind::UInt16 => Buffer::U16(vec![0; n]),
            Kind::Integer => Buffer::I32(vec![0; n]),
            Kind::UInt32 => Buffer::U32(vec![0; n]),
            Kind::Int64 => Buffer::I64(vec![0; n]),
            Kind::UInt64 => Buffer::U64(vec![0; n]),
            // FMI 1.0 and 2.0 enumerations are Integers, FMI 3.0's Int64.
            Kind::Enumeration if version == FmiVersion::Fmi3 => Buffer::I64(vec![0; n]),
            Kind::Enumeration => Buffer::I32(vec![0; n]),
            Kind::Boolean => match version {
                FmiVersion::Fmi1 => Buffer::CharBool(vec![0; n]),
                FmiVersion::Fmi2 => Buffer::IntBool(vec![0; n]),
                FmiVersion::Fmi3 => Buffer::Bool(vec![false; n]),
            },
            Kind::String => Buffer::Text(vec![String::new(); n]),
            Kind::Binary | Kind::Clock => Buffer::Bytes(vec![Vec::new(); n]),
        }
    }

    /// Element `i` as a number (NaN for text and bytes).
    fn number(&self, i: usize) -> f64 {
        match self {
            Buffer::F64(v) => v[i],
            Buffer::F32(v) => v[i] as f64,
            Buffer::I8(v) => v[i] as f64,
            Buffer::U8(v) => v[i] as f64,
            Buffer::I16(v) => v[i] as f64,
            Buffer::U16(v) => v[i] as f64,
            Buffer::I32(v) => v[i] as f64,
            Buffer::U32(v) => v[i] as f64,
            Buffer::I64(v) => v[i] as f64,
            Buffer::U64(v) => v[i] as f64,
            Buffer::IntBool(v) => (v[i] != 0) as i32 as f64,
            Buffer::Bool(v) => v[i] as i32 as f64,
            Buffer::CharBool(v) => (v[i] != 0) as i32 as f64,
            Buffer::Text(_) | Buffer::Bytes(_) => f64::NAN,
        }
    }

    /// True when an element's number does not give its text: 64-bit integers (beyond an
    /// f64's 53 bits), strings and binary.
    fn needs_text(&self) -> bool {
        matches!(self, Buffer::I64(_) | Buffer::U64(_) | Buffer::Text(_) | Buffer::Bytes(_))
    }

    /// Element `i` exactly, as text, for the kinds that [`Buffer::needs_text`]: integers in
    /// full, Binary as hexadecimal.
    fn text(&self, i: usize) -> String {
        match self {
            Buffer::I64(v) => v[i].to_string(),
            Buffer::U64(v) => v[i].to_string(),
            Buffer::Text(v) => v[i].clone(),
            Buffer::Bytes(v) => v[i].iter().map(|b| format!("{b:02x}")).collect(),
            _ => format!("{:?}", self.number(i)),
        }
    }

    /// The text of an element whose number is `x`, for the kinds a number gives exactly:
    /// integers (Integers, Enumerations and Booleans of either version) in full, as fmpy writes
    /// them, Float32 in its own shortest form, Float64 as its f64 is printed.
    fn text_of_number(&self, x: f64) -> String {
        let mut out = Vec::new();
        self.push_text_of_number(x, &mut out);
        String::from_utf8(out).unwrap_or_default()
    }

    /// Appends [`Buffer::text_of_number`]`(x)` to `out`.
    fn push_text_of_number(&self, x: f64, out: &mut Vec<u8>) {
        match self {
            Buffer::F32(_) => number_text::push_f32(x as f32, out),
            Buffer::F64(_) => number_text::push_f64(x, out),
            _ => {
                use std::io::Write;
                let _ = write!(out, "{}", x as i64);
            }
        }
    }
}

/// The variables of one type a reader gets in one call.
#[derive(Debug, Clone)]
pub(crate) struct Group {
    pub(crate) kind: Kind,
    pub(crate) vrs: Vec<u32>,
    pub(crate) buffer: Buffer,
}

/// Reads a fixed list of variables in one get call per type.
#[derive(Debug, Clone)]
pub struct Reader {
    pub(crate) groups: Vec<Group>,
    /// Per output column: its group and its element in that group's buffer.
    columns: Vec<(usize, usize)>,
    /// Only scalar Float64s, in column order: the binding reads straight into the output.
    pub(crate) direct: bool,
}

impl Reader {
    /// A reader for scalar `variables`, in order.
    pub fn new(version: FmiVersion, variables: &[&Variable]) -> Result<Reader, String> {
        Reader::with_sizes(version, variables, &vec![1; variables.len()])
    }

    /// A reader for `variables` with `sizes[k]` elements each (1 for a scalar, the product of
    /// the dimensions for an array); its columns are the elements in order, row-major.
    pub fn with_sizes(version: FmiVersion, variables: &[&Variable], sizes: &[usize]) -> Result<Reader, String> {
        let mut groups: Vec<Group> = Vec::new();
        let mut columns = Vec::new();
        let mut counts: Vec<usize> = Vec::new();
        for (v, &n) in variables.iter().zip(sizes) {
            if v.kind == Kind::Clock {
                return Err(format!("{} is a Clock; clocks cannot be recorded", v.name));
            }
            let g = match groups.iter().position(|g| g.kind == v.kind) {
                Some(g) => g,
                None => {
                    groups.push(Group { kind: v.kind, vrs: Vec::new(), buffer: Buffer::F64(Vec::new()) });
                    counts.push(0);
                    groups.len() - 1
                }
            };
            groups[g].vrs.push(v.value_reference);
            for e in 0..n {
                columns.push((g, counts[g] + e));
            }
            counts[g] += n;
        }
        for (g, n) in groups.iter_mut().zip(counts) {
            g.buffer = Buffer::new(g.kind, version, n);
        }
        let direct = groups.len() <= 1
            && groups.first().is_none_or(|g| g.kind == Kind::Real && matches!(&g.buffer, Buffer::F64(b) if b.len() == g.vrs.len()));
        Ok(Reader { groups, columns, direct })
    }

    /// Number of columns (array elements count one each).
    pub fn len(&self) -> usize {
        self.columns.len()
    }

    /// True when the reader reads nothing.
    pub fn is_empty(&self) -> bool {
        self.columns.is_empty()
    }

    /// Copies the buffers into `out` in column order, as numbers.
    pub(crate) fn gather(&self, out: &mut [f64]) {
        for (slot, &(g, i)) in out.iter_mut().zip(&self.columns) {
            *slot = self.groups[g].buffer.number(i);
        }
    }

    /// Column `c` of the last read, exactly, as text, for result files; `values` are the
    /// numbers that read gave. Float64 prints as its f64 does (`1.5`), integers in full (FMI
    /// 2.0's Integers and Booleans as f64s, `3.0`, as its result files always had them),
    /// Float32 in its own shortest form, Binary in hexadecimal.
    pub fn text(&self, c: usize, values: &[f64]) -> String {
        if self.needs_text(c) {
            let (g, i) = self.columns[c];
            return self.groups[g].buffer.text(i);
        }
        self.text_of_number(c, values[c])
    }

    /// True when column `c`'s number does not give its text (64-bit integers, String, Binary):
    /// a process that only has the numbers needs the text too.
    pub fn needs_text(&self, c: usize) -> bool {
        !self.direct && self.groups[self.columns[c].0].buffer.needs_text()
    }

    /// Column `c`'s text from its number `x`, for a column that does not [`Reader::needs_text`];
    /// needs no read (a layout of the same variables gives it).
    pub fn text_of_number(&self, c: usize, x: f64) -> String {
        if self.direct {
            // Read straight into `values`, not into the buffers.
            return number_text::f64_text(x);
        }
        self.groups[self.columns[c].0].buffer.text_of_number(x)
    }

    /// Appends [`Reader::text_of_number`]`(c, x)` to `out` (a result file's row).
    pub fn push_text_of_number(&self, c: usize, x: f64, out: &mut Vec<u8>) {
        if self.direct {
            return number_text::push_f64(x, out);
        }
        self.groups[self.columns[c].0].buffer.push_text_of_number(x, out)
    }
}
