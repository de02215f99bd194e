//! Sweep metrics: `NAME=EXPR`, where EXPR combines numbers and per-run summaries of variables
//! (`max(z_s)`, `min`, `final`, `mean`, `peak_to_peak`, `rms`; an optional second argument
//! `max(z_s, 5)` only counts samples from t = 5 s on) with + - * / and parentheses. The
//! summary `amplitude(z_s, 5, W)` is the amplitude of the sinusoid of angular frequency W
//! (rad/s) in the samples from t = 5 on: a least-squares fit of offset + cosine + sine, exact
//! for a steady sinusoidal response whatever the sampling (a sampled maximum is low by up to
//! 1 - cos(W h / 2)); W is an expression of numbers and parameter names, which the caller
//! evaluates for each run ([`Source::frequency`]). Summaries are updated sample by sample, so
//! no trajectory is stored. Metrics may also read the modes of the
//! model linearized at its initial state: `natural_frequency(N)` (rad/s) and `damping(N)` of
//! mode N, the modes numbered from 1 by rising natural frequency (the caller linearizes).
//!
//! The same grammar, with names instead of summaries, gives [`Formula`]: closed-form
//! expressions of `t` and parameters, such as the analytical references of `runner compare`.
//! Both also take `^`, the functions of [`FUNCTIONS`] (of one or two arguments) and the
//! constant `pi`.

/// A per-run statistic of one variable.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Stat {
    /// Largest sample.
    Max,
    /// Smallest sample.
    Min,
    /// Last sample.
    Final,
    /// Average of the samples (the grid is uniform, so this is the time average).
    Mean,
    /// Largest minus smallest sample.
    PeakToPeak,
    /// Root mean square of the samples.
    Rms,
    /// Amplitude of the sinusoid at the source's frequency, least-squares fitted with an offset.
    Amplitude,
}

const STATS: &[(&str, Stat)] = &[
    ("max", Stat::Max),
    ("min", Stat::Min),
    ("final", Stat::Final),
    ("mean", Stat::Mean),
    ("peak_to_peak", Stat::PeakToPeak),
    ("rms", Stat::Rms),
];

/// A quantity of one mode of the linearized model (a real eigenvalue, or a complex pair).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModeStat {
    /// |lambda| (rad/s).
    NaturalFrequency,
    /// -re(lambda) / |lambda|.
    Damping,
}

const MODE_STATS: &[(&str, ModeStat)] = &[("natural_frequency", ModeStat::NaturalFrequency), ("damping", ModeStat::Damping)];

/// Natural frequency (rad/s) and damping ratio of each mode, by rising natural frequency: what
/// [`Metrics::evaluate_with_modes`] reads (NaN for a damping ratio that is undefined, lambda = 0).
pub type ModeValues = [(f64, f64)];

/// What a summary is taken of: a variable, from a start time on.
#[derive(Debug, Clone, PartialEq)]
pub struct Source {
    /// Variable name.
    pub variable: String,
    /// Samples before this time are ignored.
    pub from: f64,
    /// `amplitude`'s angular frequency (rad/s), a formula of the run's parameters: the caller
    /// evaluates it for each run and gives it to the accumulator
    /// ([`Accumulator::set_frequency`]).
    pub frequency: Option<Formula>,
}

/// How a function an expression may call maps its arguments.
#[derive(Debug, Clone, Copy)]
pub enum Function {
    /// A function of one argument, `sqrt(x)`.
    One(fn(f64) -> f64),
    /// A function of two arguments, `atan2(y, x)`.
    Two(fn(f64, f64) -> f64),
}

impl Function {
    /// How many arguments it takes.
    pub fn arity(self) -> usize {
        match self {
            Function::One(_) => 1,
            Function::Two(_) => 2,
        }
    }
}

/// Functions an expression may call, by name. The same table, with the same names and argument
/// orders, is tests/fmpy/closed_form.py's `FUNCTIONS` (numpy's functions of the same meaning).
pub const FUNCTIONS: &[(&str, Function)] = &[
    ("exp", Function::One(f64::exp)),
    ("log", Function::One(f64::ln)),
    ("sqrt", Function::One(f64::sqrt)),
    ("sin", Function::One(f64::sin)),
    ("cos", Function::One(f64::cos)),
    ("tan", Function::One(f64::tan)),
    ("asin", Function::One(f64::asin)),
    ("acos", Function::One(f64::acos)),
    ("atan", Function::One(f64::atan)),
    // atan2(y, x): the direction of the vector (x, y), in (-pi, pi].
    ("atan2", Function::Two(f64::atan2)),
    // hypot(x, y) = sqrt(x^2 + y^2) without overflow.
    ("hypot", Function::Two(f64::hypot)),
    ("abs", Function::One(f64::abs)),
    ("ellipk", Function::One(elliptic_k)),
];

/// The one named constant: `pi` (a formula cannot take a name `pi` from its caller).
pub const CONSTANTS: &[(&str, f64)] = &[("pi", std::f64::consts::PI)];

/// The complete elliptic integral of the first kind K(m) of the parameter m = k² (scipy's
/// `ellipk` convention): pi / (2 AGM(1, sqrt(1 - m))), the arithmetic-geometric mean converging
/// quadratically to rounding; infinite at m = 1 and NaN above it.
pub fn elliptic_k(m: f64) -> f64 {
    if m.is_nan() || m > 1.0 {
        return f64::NAN;
    }
    if m == 1.0 {
        return f64::INFINITY;
    }
    let (mut a, mut b) = (1.0f64, (1.0 - m).sqrt());
    for _ in 0..60 {
        if (a - b).abs() <= 1e-16 * a {
            break;
        }
        (a, b) = (0.5 * (a + b), (a * b).sqrt());
    }
    std::f64::consts::PI / (a + b)
}

/// A parsed expression.
#[derive(Debug, Clone, PartialEq)]
pub enum Expr {
    /// A number.
    Number(f64),
    /// A statistic of source number `.1` (index into [`Metrics::sources`]).
    Summary(Stat, usize),
    /// A quantity of mode number `.1` (from 0) of the linearized model.
    Mode(ModeStat, usize),
    /// Name number `.0` of a [`Formula`] (index into [`Formula::names`]).
    Name(usize),
    /// Function number `.0` of [`FUNCTIONS`] applied to the arguments (as many as it takes).
    Call(usize, Vec<Expr>),
    /// Unary minus.
    Negate(Box<Expr>),
    /// A binary operation: one of + - * / ^.
    Binary(char, Box<Expr>, Box<Expr>),
}

/// Parses the whole of `text` in `mode`.
fn parse_all(text: &str, mode: Mode) -> Result<Expr, String> {
    let mut parser = Parser { text, pos: 0, mode };
    let expr = parser.expression()?;
    parser.skip_space();
    if parser.pos < text.len() {
        return Err(parser.error("expected an operator (+ - * / ^) or the end"));
    }
    Ok(expr)
}

/// Parsed metrics and the sources their summaries read.
#[derive(Debug, Default, Clone)]
pub struct Metrics {
    /// `(name, expression)` in command-line order.
    pub metrics: Vec<(String, Expr)>,
    /// Distinct (variable, from) pairs the expressions summarize.
    pub sources: Vec<Source>,
}

impl Metrics {
    /// Parses `NAME=EXPR` definitions.
    pub fn parse(definitions: &[String]) -> Result<Metrics, String> {
        let mut m = Metrics::default();
        for definition in definitions {
            let (name, text) = definition.split_once('=').ok_or_else(|| format!("metric '{definition}' is not of the form NAME=EXPR"))?;
            let name = name.trim();
            if name.is_empty() || name.contains(',') || name.contains('"') {
                return Err(format!("metric '{definition}': the name before '=' must be non-empty, without commas or quotes"));
            }
            if m.metrics.iter().any(|(n, _)| n == name) {
                return Err(format!("metric '{name}' is defined twice"));
            }
            let expr = parse_all(text, Mode::Metric(&mut m.sources)).map_err(|e| format!("metric '{name}': {e}"))?;
            m.metrics.push((name.to_owned(), expr));
        }
        Ok(m)
    }

    /// Fresh accumulators, one per source; those of sources whose mean or rms some metric asks
    /// for keep the sums too.
    pub fn accumulators(&self) -> Vec<Accumulator> {
        let mut sums = vec![false; self.sources.len()];
        for (_, e) in &self.metrics {
            mark_sums(e, &mut sums);
        }
        self.sources
            .iter()
            .zip(sums)
            .map(|(s, sums)| {
                let mut a = Accumulator::new(s.from, sums);
                if s.frequency.is_some() {
                    a.fit = Some(Fit::default());
                }
                a
            })
            .collect()
    }

    /// True if a summary needs a frequency from the caller (`amplitude`).
    pub fn needs_frequencies(&self) -> bool {
        self.sources.iter().any(|s| s.frequency.is_some())
    }

    /// Evaluates every metric over finished accumulators (a mode's quantity is NaN: see
    /// [`Metrics::evaluate_with_modes`]).
    pub fn evaluate(&self, acc: &[Accumulator]) -> Vec<f64> {
        self.evaluate_with_modes(acc, &[])
    }

    /// Evaluates every metric over finished accumulators and the linearized model's `modes`
    /// (a mode beyond them is NaN).
    pub fn evaluate_with_modes(&self, acc: &[Accumulator], modes: &ModeValues) -> Vec<f64> {
        let leaf = |leaf: &Expr| match leaf {
            Expr::Summary(stat, i) => acc[*i].value(*stat),
            Expr::Mode(stat, k) => modes.get(*k).map_or(f64::NAN, |(wn, zeta)| match stat {
                ModeStat::NaturalFrequency => *wn,
                ModeStat::Damping => *zeta,
            }),
            _ => f64::NAN,
        };
        self.metrics.iter().map(|(_, e)| eval(e, &leaf)).collect()
    }

    /// The highest mode number (from 1) a metric reads, if any reads one: the model must then
    /// be linearized for each run.
    pub fn highest_mode(&self) -> Option<usize> {
        fn highest(e: &Expr) -> Option<usize> {
            match e {
                Expr::Mode(_, k) => Some(k + 1),
                Expr::Number(_) | Expr::Summary(..) | Expr::Name(_) => None,
                Expr::Call(_, args) => args.iter().filter_map(highest).max(),
                Expr::Negate(a) => highest(a),
                Expr::Binary(_, a, b) => highest(a).max(highest(b)),
            }
        }
        self.metrics.iter().filter_map(|(_, e)| highest(e)).max()
    }

    /// Each metric as `NAME=EXPR` in one spelling, whatever spaces, number spellings (`0.5`,
    /// `5e-1`) or parentheses it was typed with: definitions that parse alike are spelled
    /// alike, so a sweep's record can tell whether a resumed sweep asks for the same metrics.
    pub fn canonical(&self) -> Vec<String> {
        let source = |i: usize| &self.sources[i];
        let leaf = |e: &Expr| match e {
            Expr::Summary(Stat::Amplitude, i) => {
                let s = source(*i);
                let w = s.frequency.as_ref().map_or_else(String::new, Formula::canonical);
                format!("amplitude({}, {:?}, {w})", s.variable, s.from)
            }
            Expr::Summary(stat, i) => {
                let s = source(*i);
                let word = STATS.iter().find(|(_, st)| st == stat).map_or("?", |(w, _)| w);
                if s.from == f64::NEG_INFINITY {
                    format!("{word}({})", s.variable)
                } else {
                    format!("{word}({}, {:?})", s.variable, s.from)
                }
            }
            Expr::Mode(stat, k) => {
                let word = MODE_STATS.iter().find(|(_, st)| st == stat).map_or("?", |(w, _)| w);
                format!("{word}({})", k + 1)
            }
            _ => String::new(),
        };
        self.metrics.iter().map(|(name, e)| format!("{name}={}", spell(e, &leaf))).collect()
    }
}

/// The one spelling of the definition `NAME=EXPR` ([`Metrics::canonical`]); `None` when it
/// does not parse.
pub fn canonical_definition(definition: &str) -> Option<String> {
    Metrics::parse(&[definition.to_owned()]).ok()?.canonical().pop()
}

/// `e` written out with every operation parenthesized and numbers in Rust's shortest
/// round-trip form; `leaf` spells summaries, modes and names.
fn spell(e: &Expr, leaf: &dyn Fn(&Expr) -> String) -> String {
    match e {
        Expr::Number(x) => format!("{x:?}"),
        Expr::Summary(..) | Expr::Name(_) | Expr::Mode(..) => leaf(e),
        Expr::Call(f, args) => {
            let args: Vec<String> = args.iter().map(|a| spell(a, leaf)).collect();
            format!("{}({})", FUNCTIONS[*f].0, args.join(", "))
        }
        Expr::Negate(a) => format!("(-{})", spell(a, leaf)),
        Expr::Binary(op, a, b) => format!("({} {op} {})", spell(a, leaf), spell(b, leaf)),
    }
}

/// A closed-form expression of named quantities (`t`, parameters), e.g. `2*exp(-3*t)`.
#[derive(Debug, Clone, PartialEq)]
pub struct Formula {
    /// The text it was parsed from.
    pub text: String,
    expr: Expr,
    /// The names it reads, in order of first use; `evaluate` takes their values in this order.
    pub names: Vec<String>,
}

impl Formula {
    /// Parses `text`.
    pub fn parse(text: &str) -> Result<Formula, String> {
        let mut names = Vec::new();
        let expr = parse_all(text, Mode::Formula(&mut names))?;
        Ok(Formula { text: text.to_owned(), expr, names })
    }

    /// The expression in one spelling (as [`Metrics::canonical`]).
    pub fn canonical(&self) -> String {
        spell(&self.expr, &|e| if let Expr::Name(i) = e { self.names[*i].clone() } else { String::new() })
    }

    /// The value, given the values of [`Formula::names`] in order.
    pub fn evaluate(&self, values: &[f64]) -> f64 {
        eval(&self.expr, &|leaf| if let Expr::Name(i) = leaf { values[*i] } else { f64::NAN })
    }
}

/// Sets `sums[i]` for every source `i` of which `e` takes a mean or an rms.
fn mark_sums(e: &Expr, sums: &mut [bool]) {
    match e {
        Expr::Summary(Stat::Mean | Stat::Rms, i) => sums[*i] = true,
        Expr::Number(_) | Expr::Summary(..) | Expr::Name(_) | Expr::Mode(..) => {}
        Expr::Call(_, args) => args.iter().for_each(|a| mark_sums(a, sums)),
        Expr::Negate(a) => mark_sums(a, sums),
        Expr::Binary(_, a, b) => {
            mark_sums(a, sums);
            mark_sums(b, sums);
        }
    }
}

/// Evaluates `e`; `leaf` gives the value of summaries and names.
fn eval(e: &Expr, leaf: &dyn Fn(&Expr) -> f64) -> f64 {
    match e {
        Expr::Number(x) => *x,
        Expr::Summary(..) | Expr::Name(_) | Expr::Mode(..) => leaf(e),
        Expr::Call(f, args) => match FUNCTIONS[*f].1 {
            Function::One(f) => f(eval(&args[0], leaf)),
            Function::Two(f) => f(eval(&args[0], leaf), eval(&args[1], leaf)),
        },
        Expr::Negate(a) => -eval(a, leaf),
        Expr::Binary(op, a, b) => {
            let (a, b) = (eval(a, leaf), eval(b, leaf));
            match op {
                '+' => a + b,
                '-' => a - b,
                '*' => a * b,
                '^' => a.powf(b),
                _ => a / b,
            }
        }
    }
}

/// Streaming statistics of one source.
#[derive(Debug, Clone)]
pub struct Accumulator {
    /// Samples before this time are skipped: `from` less a rounding allowance, so `from = 5`
    /// includes the grid point 4.999999999999999.
    threshold: f64,
    /// Whether the sums (for mean and rms) are kept: a sweep's usual metrics (max, min,
    /// peak_to_peak, final) need none, and the two sums were a third of every sample's cost.
    sums: bool,
    count: usize,
    min: f64,
    max: f64,
    sum: f64,
    sum_squares: f64,
    last: f64,
    /// `amplitude`'s least-squares sums (`None` for the other summaries).
    fit: Option<Fit>,
}

/// The sums of a least-squares fit x ~ a + b cos(w (t - t0)) + c sin(w (t - t0)) over the
/// counted samples (t0: the first one's time, so the phases stay small numbers): the normal
/// equations' matrix and right-hand side, accumulated sample by sample.
#[derive(Debug, Clone, Default)]
struct Fit {
    /// The angular frequency w (rad/s); `None` until the caller sets it.
    omega: Option<f64>,
    t0: Option<f64>,
    /// Sums of c, s, c^2, s^2, c s, x c, x s and x (the count is the accumulator's).
    c: f64,
    s: f64,
    cc: f64,
    ss: f64,
    cs: f64,
    xc: f64,
    xs: f64,
    x: f64,
}

impl Fit {
    #[inline]
    fn add(&mut self, t: f64, x: f64) {
        let Some(w) = self.omega else { return };
        let t0 = *self.t0.get_or_insert(t);
        let (s, c) = (w * (t - t0)).sin_cos();
        self.c += c;
        self.s += s;
        self.cc += c * c;
        self.ss += s * s;
        self.cs += c * s;
        self.xc += x * c;
        self.xs += x * s;
        self.x += x;
    }

    /// sqrt(b^2 + c^2) of the fit over `n` samples, by Cramer's rule on the 3x3 normal
    /// equations; NaN without a frequency or when they are singular (fewer than three
    /// samples, or a frequency of zero).
    fn amplitude(&self, n: f64) -> f64 {
        if self.omega.is_none() {
            return f64::NAN;
        }
        let m = [[n, self.c, self.s], [self.c, self.cc, self.cs], [self.s, self.cs, self.ss]];
        let r = [self.x, self.xc, self.xs];
        let det3 = |m: &[[f64; 3]; 3]| {
            m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
                + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
        };
        let d = det3(&m);
        // Relative to the matrix's scale (n^3): below this the sines and cosines are not
        // independent of the offset (a zero frequency, or a window of a few samples).
        if d.is_nan() || d.abs() <= 1e-12 * n * n * n {
            return f64::NAN;
        }
        let column = |k: usize| {
            let mut mk = m;
            for (row, v) in mk.iter_mut().zip(r) {
                row[k] = v;
            }
            det3(&mk) / d
        };
        column(1).hypot(column(2))
    }
}

impl Accumulator {
    fn new(from: f64, sums: bool) -> Accumulator {
        Accumulator {
            threshold: from - 1e-9 * from.abs().max(1.0),
            sums,
            count: 0,
            min: f64::INFINITY,
            max: f64::NEG_INFINITY,
            sum: 0.0,
            sum_squares: 0.0,
            last: f64::NAN,
            fit: None,
        }
    }

    /// Sets `amplitude`'s angular frequency (rad/s) for this run, before its first sample.
    pub fn set_frequency(&mut self, omega: f64) {
        if let Some(fit) = self.fit.as_mut() {
            fit.omega = Some(omega);
        }
    }

    /// Adds the sample `x` taken at time `t`.
    #[inline]
    pub fn add(&mut self, t: f64, x: f64) {
        if t < self.threshold {
            return;
        }
        self.add_counted(x);
        if let Some(fit) = self.fit.as_mut() {
            fit.add(t, x);
        }
    }

    /// Whether every sample counts (no `from` time) and none needs its time (`amplitude`):
    /// then [`Accumulator::add_counted`] does what [`Accumulator::add`] does, without the time
    /// test.
    pub fn counts_all(&self) -> bool {
        self.threshold == f64::NEG_INFINITY && self.fit.is_none()
    }

    /// Adds the sample `x`, which counts whatever its time.
    #[inline]
    pub fn add_counted(&mut self, x: f64) {
        self.count += 1;
        // Plain comparisons, not f64::min/max: samples are finite (fmi2GetReal refuses others,
        // and a NaN would be skipped here too), and this is one instruction each per sample.
        if x < self.min {
            self.min = x;
        }
        if x > self.max {
            self.max = x;
        }
        if self.sums {
            self.sum += x;
            self.sum_squares += x * x;
        }
        self.last = x;
    }

    /// The statistic; NaN when no sample was counted.
    pub fn value(&self, stat: Stat) -> f64 {
        if self.count == 0 {
            return f64::NAN;
        }
        let n = self.count as f64;
        match stat {
            Stat::Max => self.max,
            Stat::Min => self.min,
            Stat::Final => self.last,
            Stat::Mean | Stat::Rms if !self.sums => unreachable!("Metrics::accumulators keeps the sums of every mean and rms"),
            Stat::Mean => self.sum / n,
            Stat::PeakToPeak => self.max - self.min,
            Stat::Rms => (self.sum_squares / n).sqrt(),
            Stat::Amplitude => self.fit.as_ref().map_or(f64::NAN, |fit| fit.amplitude(n)),
        }
    }
}

/// What leaves an expression may have: summaries of variables (metrics) or bare names (formulas).
enum Mode<'s> {
    Metric(&'s mut Vec<Source>),
    Formula(&'s mut Vec<String>),
}

/// Recursive descent over `expr := term (('+'|'-') term)*`, `term := unary (('*'|'/') unary)*`,
/// `unary := '-' unary | power`, `power := atom ['^' unary]` (so -x^2 = -(x^2), 2^-1 = 0.5),
/// `atom := NUMBER | '(' expr ')' | FUNCTION '(' expr (',' expr)* ')' | 'pi' | leaf`, where a leaf is
/// `STAT '(' VARIABLE [',' NUMBER] ')'` for metrics and `NAME` for formulas.
struct Parser<'t, 's> {
    text: &'t str,
    pos: usize,
    mode: Mode<'s>,
}

impl Parser<'_, '_> {
    fn error(&self, what: &str) -> String {
        let found = match self.rest().chars().next() {
            Some(c) => format!("'{c}'"),
            None => "the end".to_owned(),
        };
        format!("{what} at column {} of '{}', found {found}", self.pos + 1, self.text)
    }

    fn rest(&self) -> &str {
        &self.text[self.pos..]
    }

    fn skip_space(&mut self) {
        let trimmed = self.rest().trim_start();
        self.pos = self.text.len() - trimmed.len();
    }

    fn eat(&mut self, c: char) -> bool {
        self.skip_space();
        if self.rest().starts_with(c) {
            self.pos += c.len_utf8();
            true
        } else {
            false
        }
    }

    fn expression(&mut self) -> Result<Expr, String> {
        let mut left = self.term()?;
        loop {
            let op = if self.eat('+') {
                '+'
            } else if self.eat('-') {
                '-'
            } else {
                return Ok(left);
            };
            left = Expr::Binary(op, Box::new(left), Box::new(self.term()?));
        }
    }

    fn term(&mut self) -> Result<Expr, String> {
        let mut left = self.unary()?;
        loop {
            let op = if self.eat('*') {
                '*'
            } else if self.eat('/') {
                '/'
            } else {
                return Ok(left);
            };
            left = Expr::Binary(op, Box::new(left), Box::new(self.unary()?));
        }
    }

    fn unary(&mut self) -> Result<Expr, String> {
        if self.eat('-') {
            return Ok(Expr::Negate(Box::new(self.unary()?)));
        }
        let base = self.atom()?;
        if self.eat('^') {
            return Ok(Expr::Binary('^', Box::new(base), Box::new(self.unary()?)));
        }
        Ok(base)
    }

    fn atom(&mut self) -> Result<Expr, String> {
        if self.eat('(') {
            let e = self.expression()?;
            if !self.eat(')') {
                return Err(self.error("expected ')'"));
            }
            return Ok(e);
        }
        self.skip_space();
        let c = self.rest().chars().next();
        if matches!(c, Some(c) if c.is_ascii_digit() || c == '.') {
            return Ok(Expr::Number(self.number()?));
        }
        if matches!(c, Some(c) if c.is_alphabetic() || c == '_') {
            return self.word();
        }
        Err(self.error(match self.mode {
            Mode::Metric(_) => "expected a number, '(' or a summary such as max(x)",
            Mode::Formula(_) => "expected a number, '(', a function such as exp(...) or a name",
        }))
    }

    /// A word: a function call, the constant `pi`, a summary (metrics) or a name (formulas).
    fn word(&mut self) -> Result<Expr, String> {
        let start = self.pos;
        let len: usize = self.rest().chars().take_while(|&c| c.is_alphanumeric() || c == '_').map(char::len_utf8).sum();
        let word = self.rest()[..len].to_owned();
        let called = self.rest()[len..].trim_start().starts_with('(');
        if let Some(f) = FUNCTIONS.iter().position(|(n, _)| *n == word.as_str()).filter(|_| called) {
            self.pos += len;
            self.eat('(');
            let mut args = vec![self.expression()?];
            while self.eat(',') {
                args.push(self.expression()?);
            }
            if !self.eat(')') {
                return Err(self.error("expected ',' or ')'"));
            }
            let arity = FUNCTIONS[f].1.arity();
            if args.len() != arity {
                let plural = |n: usize| if n == 1 { "argument" } else { "arguments" };
                return Err(format!(
                    "'{word}' at column {} of '{}' takes {arity} {}, given {}",
                    start + 1,
                    self.text,
                    plural(arity),
                    args.len()
                ));
            }
            return Ok(Expr::Call(f, args));
        }
        if let Some((_, value)) = CONSTANTS.iter().find(|(n, _)| *n == word.as_str()).filter(|_| !called) {
            self.pos += len;
            return Ok(Expr::Number(*value));
        }
        if let Mode::Formula(names) = &mut self.mode {
            if called {
                let known: Vec<&str> = FUNCTIONS.iter().map(|(n, _)| *n).collect();
                return Err(format!(
                    "'{word}' at column {} of '{}' is not a function; use one of {}",
                    self.pos + 1,
                    self.text,
                    known.join(", ")
                ));
            }
            let index = match names.iter().position(|n| *n == word) {
                Some(i) => i,
                None => {
                    names.push(word);
                    names.len() - 1
                }
            };
            self.pos += len;
            return Ok(Expr::Name(index));
        }
        if let Some((_, stat)) = MODE_STATS.iter().find(|(n, _)| *n == word.as_str()).filter(|_| called) {
            self.pos += len;
            self.eat('(');
            self.skip_space();
            let at = self.pos;
            let n = self.number()?;
            if !(n >= 1.0 && n.fract() == 0.0 && n <= 1e6) {
                self.pos = at;
                return Err(self.error(&format!("{word}(N) takes a mode number N = 1, 2, ... (modes by rising natural frequency)")));
            }
            if !self.eat(')') {
                return Err(self.error("expected ')'"));
            }
            return Ok(Expr::Mode(*stat, n as usize - 1));
        }
        self.summary()
    }

    fn number(&mut self) -> Result<f64, String> {
        self.skip_space();
        let bytes = self.rest().as_bytes();
        let mut end = 0;
        while end < bytes.len() {
            let b = bytes[end];
            let exponent_sign = (b == b'+' || b == b'-') && end > 0 && matches!(bytes[end - 1], b'e' | b'E');
            if b.is_ascii_digit() || b == b'.' || b == b'e' || b == b'E' || exponent_sign {
                end += 1;
            } else {
                break;
            }
        }
        let text = &self.rest()[..end];
        let value = text.parse::<f64>().map_err(|_| {
            if text.is_empty() {
                self.error("expected a number")
            } else {
                self.error(&format!("'{text}' is not a number"))
            }
        })?;
        self.pos += end;
        Ok(value)
    }

    /// A bare name (letters, digits, `_`, `.`, `[`, `]`) or a name in single quotes.
    fn variable_name(&mut self) -> Result<String, String> {
        self.skip_space();
        if self.rest().starts_with('\'') {
            let close = self.rest()[1..].find('\'').ok_or_else(|| self.error("unterminated quoted variable name"))?;
            let name = self.rest()[1..1 + close].to_owned();
            self.pos += close + 2;
            return Ok(name);
        }
        let len: usize =
            self.rest().chars().take_while(|&c| c.is_alphanumeric() || matches!(c, '_' | '.' | '[' | ']')).map(char::len_utf8).sum();
        if len == 0 {
            return Err(self.error("expected a variable name"));
        }
        let name = self.rest()[..len].to_owned();
        self.pos += len;
        Ok(name)
    }

    fn summary(&mut self) -> Result<Expr, String> {
        let start = self.pos;
        let len: usize = self.rest().chars().take_while(|&c| c.is_alphanumeric() || c == '_').map(char::len_utf8).sum();
        let word = self.rest()[..len].to_owned();
        if word == "amplitude" {
            return self.amplitude(len);
        }
        let mut names: Vec<&str> = STATS.iter().map(|(n, _)| *n).collect();
        names.push("amplitude");
        let stat = STATS.iter().find(|(n, _)| *n == word.as_str()).map(|(_, s)| *s).ok_or_else(|| {
            format!(
                "'{word}' at column {} of '{}' is not a summary; use one of {}, e.g. max(x), or a mode's natural_frequency(N) or damping(N)",
                start + 1,
                self.text,
                names.join(", ")
            )
        })?;
        self.pos += len;
        if !self.eat('(') {
            return Err(self.error(&format!("expected '(' after {word}")));
        }
        let variable = self.variable_name()?;
        let from = if self.eat(',') {
            self.skip_space();
            self.number()?
        } else {
            f64::NEG_INFINITY
        };
        if !self.eat(')') {
            return Err(self.error("expected ')'"));
        }
        self.source(Source { variable, from, frequency: None }, stat)
    }

    /// `amplitude(VARIABLE, FROM, W)` (the word of `len` bytes at the cursor): W is a formula
    /// of numbers and parameter names, parsed up to the closing ')'.
    fn amplitude(&mut self, len: usize) -> Result<Expr, String> {
        let usage = "amplitude(VARIABLE, FROM, W) takes the variable, the time from which the response is steady and its angular frequency W (rad/s, an expression of parameters such as 2*pi*speed/road_wavelength)";
        self.pos += len;
        if !self.eat('(') {
            return Err(self.error("expected '(' after amplitude"));
        }
        let variable = self.variable_name()?;
        if !self.eat(',') {
            return Err(self.error(usage));
        }
        self.skip_space();
        let from = self.number()?;
        if !from.is_finite() {
            return Err(self.error(usage));
        }
        if !self.eat(',') {
            return Err(self.error(usage));
        }
        self.skip_space();
        let begin = self.pos;
        let mut names = Vec::new();
        let mut inner = Parser { text: self.text, pos: self.pos, mode: Mode::Formula(&mut names) };
        let expr = inner.expression()?;
        let end = inner.pos;
        self.pos = end;
        if !self.eat(')') {
            return Err(self.error("expected ')' after amplitude's frequency"));
        }
        let frequency = Formula { text: self.text[begin..end].trim().to_owned(), expr, names };
        self.source(Source { variable, from, frequency: Some(frequency) }, Stat::Amplitude)
    }

    /// The summary `stat` of `source`, which joins the sources unless it is there already.
    fn source(&mut self, source: Source, stat: Stat) -> Result<Expr, String> {
        let Mode::Metric(sources) = &mut self.mode else { unreachable!("summaries are parsed in metric mode only") };
        let index = match sources.iter().position(|s| *s == source) {
            Some(i) => i,
            None => {
                sources.push(source);
                sources.len() - 1
            }
        };
        Ok(Expr::Summary(stat, index))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Definitions typed with other spaces, number spellings or redundant parentheses have one
    /// spelling; definitions that compute something else (another operand order, source, start
    /// time, frequency or mode) keep theirs apart; and a spelling parses back to itself.
    #[test]
    fn definitions_that_parse_alike_are_spelled_alike() {
        let spelled = |d: &str| canonical_definition(d).unwrap_or_else(|| panic!("{d} does not parse"));
        let alike = [
            ["t=max(z_s)/max(z_r)", " t = ( max( z_s ) ) / max(z_r ) "],
            ["a=final(x, 5)", "a=final(x,5.0)"],
            ["a=-2*rms(x)", "a=-(2) * rms(x)"],
            ["a=amplitude(x, 5, 2*pi*speed/lambda)", "a=amplitude(x,5e0, 2 * pi*speed / lambda)"],
            ["a=damping(1) + 1e-3", "a=damping( 1 )+0.001"],
            ["a=hypot(max(x), 2^3)", "a=hypot( max(x),(2)^3 )"],
        ];
        for [a, b] in alike {
            assert_eq!(spelled(a), spelled(b), "{a} and {b}");
            assert_eq!(spelled(&spelled(a)), spelled(a), "{a} spelled again");
        }
        let apart = [
            ["a=max(x)*2", "a=2*max(x)"],
            ["a=max(x)", "a=max(y)"],
            ["a=max(x)", "a=max(x, 0)"],
            ["a=max(x)", "b=max(x)"],
            ["a=amplitude(x, 5, w)", "a=amplitude(x, 5, 2*w)"],
            ["a=damping(1)", "a=damping(2)"],
            ["a=1-2-3", "a=1-(2-3)"],
        ];
        for [a, b] in apart {
            assert_ne!(spelled(a), spelled(b), "{a} and {b}");
        }
        assert_eq!(canonical_definition("a=max("), None);
    }

    /// K(m) against tabulated values (K(0) = pi/2, K(1/2) = 1.854074677301372,
    /// K(sin²60°) = 2.156515647499643) and the series pi/2 (1 + m/4 + 9 m²/64) for small m.
    #[test]
    fn the_elliptic_integral_matches_its_tables() {
        assert_eq!(elliptic_k(0.0), std::f64::consts::FRAC_PI_2);
        assert!((elliptic_k(0.5) - 1.854_074_677_301_372).abs() < 1e-15);
        assert!((elliptic_k(0.75) - 2.156_515_647_499_643).abs() < 1e-14);
        let m = 1e-3;
        assert!((elliptic_k(m) / (std::f64::consts::FRAC_PI_2 * (1.0 + m / 4.0 + 9.0 * m * m / 64.0)) - 1.0).abs() < 1e-9);
        assert!(elliptic_k(1.0).is_infinite() && elliptic_k(1.5).is_nan());
        assert_eq!(Formula::parse("ellipk(m)").unwrap().evaluate(&[0.5]), elliptic_k(0.5));
    }

    /// Mode quantities read the modes given, by number from 1; one beyond them is NaN, and a
    /// mode number that is not a whole number from 1 is refused.
    #[test]
    fn modes_are_read_by_number() {
        let m = Metrics::parse(&["z=damping(2)".to_owned(), "f=natural_frequency(1) / (2*pi) + max(x)".to_owned()]).unwrap();
        assert_eq!(m.highest_mode(), Some(2));
        let mut acc = m.accumulators();
        acc[0].add(0.0, 1.0);
        let v = m.evaluate_with_modes(&acc, &[(6.0, 0.5), (20.0, 0.1)]);
        assert_eq!(v[0], 0.1);
        assert_eq!(v[1], 6.0 / (2.0 * std::f64::consts::PI) + 1.0);
        assert!(m.evaluate_with_modes(&acc, &[(6.0, 0.5)])[0].is_nan());
        assert!(m.evaluate(&acc)[0].is_nan());
        assert_eq!(Metrics::parse(&["a=max(x)".to_owned()]).unwrap().highest_mode(), None);
        for bad in ["a=damping(0)", "a=damping(1.5)", "a=damping(x)"] {
            let err = Metrics::parse(&[bad.to_owned()]).unwrap_err();
            assert!(err.contains("takes a mode number") || err.contains("expected a number"), "{bad}: {err}");
        }
    }

    fn run(definition: &str, samples: &[(f64, &[f64])]) -> Result<f64, String> {
        let m = Metrics::parse(&[definition.to_owned()])?;
        let mut acc = m.accumulators();
        for (t, values) in samples {
            for (a, x) in acc.iter_mut().zip(values.iter()) {
                a.add(*t, *x);
            }
        }
        Ok(m.evaluate(&acc)[0])
    }

    /// Only sources of a mean or an rms keep the sums, wherever in an expression (a function's
    /// argument, under a minus, in a second metric) that summary is; and with or without
    /// them the statistics are those of the samples.
    #[test]
    fn sums_are_kept_for_the_sources_of_means_and_rms_only() {
        let definitions = ["a=max(x)/min(y) + peak_to_peak(z) + final(w)", "b=sqrt(rms(y, 1))", "c=-mean(z) * max(w, 1)"];
        let m = Metrics::parse(&definitions.map(str::to_owned)).unwrap();
        let names: Vec<(&str, f64)> = m.sources.iter().map(|s| (s.variable.as_str(), s.from)).collect();
        let sums: Vec<bool> = m.accumulators().iter().map(|a| a.sums).collect();
        let all = f64::NEG_INFINITY;
        let expected = [("x", all, false), ("y", all, false), ("z", all, true), ("w", all, false), ("y", 1.0, true), ("w", 1.0, false)];
        assert_eq!(names, expected.map(|(v, from, _)| (v, from)));
        assert_eq!(sums, expected.map(|(.., sums)| sums));
        let mut acc = m.accumulators();
        for (t, x) in [(0.0, 1.0), (1.0, 3.0), (2.0, 2.0)] {
            for a in acc.iter_mut() {
                a.add(t, x);
            }
        }
        // Every source sees 1, 3, 2 (from t = 1 on: 3, 2).
        assert_eq!(m.evaluate(&acc), [3.0 + 2.0 + 2.0, (13.0f64 / 2.0).sqrt().sqrt(), -2.0 * 3.0]);
    }

    /// The sweep leaves out the time test when no summary has a `from` time: `add_counted`
    /// then gives what `add` gives, and only `from`-less sources say they count all samples.
    #[test]
    fn counting_every_sample_without_the_time_test_changes_nothing() {
        let m = Metrics::parse(&["a=rms(x) + peak_to_peak(x) + final(x) + max(x, 1)".to_owned()]).unwrap();
        assert_eq!(m.accumulators().iter().map(Accumulator::counts_all).collect::<Vec<_>>(), [true, false]);
        let (mut timed, mut counted) = (m.accumulators(), m.accumulators());
        for (t, x) in [(0.0, 1.0), (1.0, -3.0), (2.0, 2.5)] {
            timed[0].add(t, x);
            counted[0].add_counted(x);
        }
        for stat in [Stat::Max, Stat::Min, Stat::Final, Stat::Mean, Stat::PeakToPeak, Stat::Rms] {
            assert_eq!(timed[0].value(stat).to_bits(), counted[0].value(stat).to_bits(), "{stat:?}");
        }
    }

    #[test]
    fn precedence_parentheses_and_unary_minus() {
        // x samples 1, 3, 2 (one source): max 3, min 1, final 2, mean 2.
        let s: &[(f64, &[f64])] = &[(0.0, &[1.0]), (1.0, &[3.0]), (2.0, &[2.0])];
        assert_eq!(run("a=1 + 2 * 3", s).unwrap(), 7.0);
        assert_eq!(run("a=(1 + 2) * 3", s).unwrap(), 9.0);
        assert_eq!(run("a=-max(x) - -1", s).unwrap(), -2.0);
        assert_eq!(run("a=max(x)/min(x) + final(x) * mean(x)", s).unwrap(), 7.0);
        assert_eq!(run("a=peak_to_peak(x)", s).unwrap(), 2.0);
        assert_eq!(run("a=1.5e1/3", s).unwrap(), 5.0);
        assert_eq!(run("a=max(x, 1.5)", s).unwrap(), 2.0, "the window starts after the peak at t = 1");
        assert!((run("a=rms(x)", s).unwrap() - (14.0f64 / 3.0).sqrt()).abs() < 1e-15);
    }

    #[test]
    fn functions_and_powers_in_metrics() {
        let s: &[(f64, &[f64])] = &[(0.0, &[4.0])];
        assert_eq!(run("a=sqrt(max(x)) + 2^3", s).unwrap(), 10.0);
        assert_eq!(run("a=-2^2", s).unwrap(), -4.0, "unary minus binds looser than ^");
        assert_eq!(run("a=2^-1", s).unwrap(), 0.5);
        assert_eq!(run("a=2^3^2", s).unwrap(), 512.0, "^ is right-associative");
    }

    #[test]
    fn formulas_read_names_and_call_functions() {
        let f = Formula::parse("a * exp(-2*t) + sin(t)^2 + cos(t)^2").unwrap();
        assert_eq!(f.names, ["a", "t"]);
        let (a, t) = (7.5f64, 0.3f64);
        assert!((f.evaluate(&[a, t]) - (a * (-2.0 * t).exp() + 1.0)).abs() < 1e-15);
        assert!(Formula::parse("exq(t)").unwrap_err().contains("'exq' at column 1 of 'exq(t)' is not a function; use one of exp"));
        assert!(Formula::parse("max(t)").unwrap_err().contains("not a function"), "summaries belong to metrics only");
        assert!(Formula::parse("2 t").unwrap_err().contains("expected an operator"));
        assert!(
            Metrics::parse(&["a=t".into()]).unwrap_err().contains("'t' at column 1 of 't' is not a summary"),
            "metrics take no bare names"
        );
    }

    /// The inverse trigonometric functions, atan2 and hypot (two arguments, y before x as in C
    /// and numpy) and the constant pi, each against f64's own function: the evaluator must add
    /// nothing to them (exact equality).
    #[test]
    fn two_argument_functions_and_pi() {
        let eval = |text: &str, values: &[f64]| Formula::parse(text).unwrap().evaluate(values);
        assert_eq!(eval("atan2(y, x)", &[-1.0, -2.0]), (-1.0f64).atan2(-2.0));
        assert_eq!(eval("atan2(1, -1)", &[]), 0.75 * std::f64::consts::PI, "the second quadrant, not atan(-1)");
        assert_eq!(eval("hypot(3, 4)", &[]), 5.0);
        assert_eq!(eval("hypot(a - 1, 2*b)", &[4.0, 2.0]), 5.0, "arguments are whole expressions");
        assert_eq!(eval("asin(x) + acos(x)", &[0.3]), 0.3f64.asin() + 0.3f64.acos());
        assert_eq!(eval("atan(x)", &[0.5]), 0.5f64.atan());
        assert_eq!(eval("abs(-x)", &[2.5]), 2.5);
        assert_eq!(eval("pi", &[]), std::f64::consts::PI);
        assert_eq!(eval("2*pi - atan2(0, -1)", &[]), std::f64::consts::PI);
        let f = Formula::parse("r*cos(pi/2 + theta)").unwrap();
        assert_eq!(f.names, ["r", "theta"], "pi is a constant, not a name the caller gives");
        assert!(eval("acos(1.5)", &[]).is_nan(), "outside the domain: NaN, as f64::acos");
        assert_eq!(run("a=pi*max(x)", &[(0.0, &[2.0])]).unwrap(), 2.0 * std::f64::consts::PI, "metrics take pi too");
    }

    /// A call with the wrong number of arguments, or of a function that does not exist, is
    /// refused naming the function, the count and the place.
    #[test]
    fn wrong_argument_counts_and_unknown_functions_are_refused() {
        let e = Formula::parse("atan2(y)").unwrap_err();
        assert_eq!(e, "'atan2' at column 1 of 'atan2(y)' takes 2 arguments, given 1");
        let e = Formula::parse("1 + sqrt(x, y)").unwrap_err();
        assert_eq!(e, "'sqrt' at column 5 of '1 + sqrt(x, y)' takes 1 argument, given 2");
        let e = Formula::parse("hypot(x, y, z)").unwrap_err();
        assert!(e.contains("takes 2 arguments, given 3"), "{e}");
        let e = Formula::parse("atan2(y, x").unwrap_err();
        assert!(e.contains("expected ',' or ')'"), "{e}");
        let e = Formula::parse("atan2(y,)").unwrap_err();
        assert!(e.contains("expected a number, '(', a function"), "{e}");
        let e = Formula::parse("arctan2(y, x)").unwrap_err();
        assert!(e.contains("'arctan2' at column 1") && e.contains("is not a function") && e.contains("atan2, hypot"), "{e}");
        let e = Formula::parse("pi(2)").unwrap_err();
        assert!(e.contains("'pi' at column 1 of 'pi(2)' is not a function"), "{e}");
        let e = Metrics::parse(&["a=atan2(max(y))".into()]).unwrap_err();
        assert!(e.contains("takes 2 arguments, given 1"), "{e}");
    }

    /// `amplitude` fits offset + cosine + sine at the given frequency: on samples of
    /// 0.3 + 1.7 sin(w t + 0.4) every 0.1 s at w = 5 rad/s (eight samples a period, 2.3
    /// periods from t = 1) it gives 1.7 to rounding, where the sampled maximum is low (here by
    /// 3.5e-4; by up to 1 - cos(w h / 2) = 3 %); without its frequency, or on two samples, it is NaN. The
    /// frequency is a formula of the caller's names, and a source of its own.
    #[test]
    fn amplitude_fits_the_sinusoid_at_its_frequency() {
        let text = "a=amplitude(x, 1, 2*pi*f/p) - max(x, 1) + amplitude(x, 1, w)";
        let m = Metrics::parse(&[text.to_owned()]).unwrap();
        assert_eq!(m.sources.len(), 3, "{:?}", m.sources);
        let frequency = m.sources[0].frequency.as_ref().unwrap();
        assert_eq!((frequency.text.as_str(), frequency.names.clone()), ("2*pi*f/p", vec!["f".to_owned(), "p".to_owned()]));
        assert_eq!(m.sources[1].frequency, None);
        assert!(m.needs_frequencies());
        let w = 5.0;
        let mut acc = m.accumulators();
        assert!(!acc[0].counts_all() && !acc[2].counts_all());
        acc[0].set_frequency(frequency.evaluate(&[w / (2.0 * std::f64::consts::PI), 1.0]));
        acc[2].set_frequency(w);
        for k in 0..=40 {
            let t = 0.1 * k as f64;
            let x = 0.3 + 1.7 * (w * t + 0.4).sin();
            for a in acc.iter_mut() {
                a.add(t, x);
            }
        }
        for a in [&acc[0], &acc[2]] {
            assert!((a.value(Stat::Amplitude) - 1.7).abs() < 1e-13, "{}", a.value(Stat::Amplitude));
        }
        let sampled = acc[1].value(Stat::Max) - 0.3;
        assert!(sampled < 1.7 - 1e-4 && sampled > 1.7 * (w * 0.1 / 2.0).cos(), "{sampled}: low, within the bound");
        let mut unset = m.accumulators();
        let mut short = m.accumulators();
        short[0].set_frequency(w);
        for k in 10..=30 {
            unset[0].add(0.1 * k as f64, 1.0);
        }
        short[0].add(1.0, 1.0);
        short[0].add(1.1, 2.0);
        assert!(unset[0].value(Stat::Amplitude).is_nan(), "no frequency given");
        assert!(short[0].value(Stat::Amplitude).is_nan(), "two samples do not fix three coefficients");
        for bad in ["a=amplitude(x)", "a=amplitude(x, 1)", "a=amplitude(x, 1, max(y))", "a=amplitude(x, 1, w"] {
            assert!(Metrics::parse(&[bad.to_owned()]).is_err(), "{bad}");
        }
        let e = Metrics::parse(&["a=amplitude(x, 1)".to_owned()]).unwrap_err();
        assert!(e.contains("amplitude(VARIABLE, FROM, W)"), "{e}");
    }

    #[test]
    fn sources_are_shared_between_summaries() {
        let m = Metrics::parse(&["t=max(z_s)/max(z_r)".into(), "p=peak_to_peak(z_s)".into()]).unwrap();
        let names: Vec<&str> = m.sources.iter().map(|s| s.variable.as_str()).collect();
        assert_eq!(names, ["z_s", "z_r"]);
    }

    #[test]
    fn errors_say_where() {
        let e = Metrics::parse(&["t=max(z_s".into()]).unwrap_err();
        assert!(e.contains("expected ')'") && e.contains("column 8 of 'max(z_s'"), "{e}");
        let e = Metrics::parse(&["t=maximum(z_s)".into()]).unwrap_err();
        assert!(e.contains("'maximum'") && e.contains("peak_to_peak"), "{e}");
        let e = Metrics::parse(&["t=max(z_s) max(z_r)".into()]).unwrap_err();
        assert!(e.contains("expected an operator"), "{e}");
        assert!(Metrics::parse(&["no_equals".into()]).unwrap_err().contains("NAME=EXPR"));
        assert!(Metrics::parse(&["t=1..2".into()]).unwrap_err().contains("not a number"));
        // A start time that is not a number is named as missing, not as the empty text ''.
        let e = Metrics::parse(&["t=max(z_s,abc)".into()]).unwrap_err();
        assert!(e.contains("expected a number at column 9 of 'max(z_s,abc)', found 'a'"), "{e}");
    }
}
