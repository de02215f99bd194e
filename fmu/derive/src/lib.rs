//! Derive macros of the export toolkit (re-exported by `fmu-export`, which models depend on).
//!
//! `#[derive(Variables)]` turns a model struct whose fields carry `#[parameter(...)]`,
//! `#[input(...)]` or `#[output(...)]` into its variable table: each variable is declared once,
//! on its field, with its doc comment as the description. `#[derive(StateVector)]` names the
//! components of the state vector: their table rows, index constants, and `load`/`store`
//! between the struct and the solver's slice. The generated code is documented on the traits
//! `fmu_export::Variables` and `fmu_export::StateVector`.

use proc_macro::TokenStream;
use proc_macro2::{Span, TokenStream as Tokens};
use quote::{format_ident, quote};
use syn::parse::Parse;
use syn::spanned::Spanned;
use syn::{parse_macro_input, Data, DeriveInput, Error, Expr, Field, Fields, Ident, LitStr, Result, Type, WherePredicate};

/// The variable table of a model struct (see `fmu_export::Variables`; a whole model is the
/// example of the `fmu_export` crate's documentation).
///
/// ```
/// use fmu_export::{Causality, Variables};
///
/// #[derive(Debug, Clone, Variables)]
/// pub struct Spring {
///     /// Stiffness
///     #[parameter(unit = "N/m", positive)]
///     pub k: f64,
///     /// Force on the mass
///     #[output(name = "F", unit = "N")]
///     pub force: f64,
/// }
///
/// let table = Spring::variables();
/// let rows: Vec<_> = table.iter().map(|v| (v.name, v.causality)).collect();
/// assert_eq!(rows, [("k", Causality::Parameter), ("F", Causality::Output)]);
/// ```
#[proc_macro_derive(Variables, attributes(variables, parameter, input, output, derived))]
pub fn derive_variables(input: TokenStream) -> TokenStream {
    let input = parse_macro_input!(input as DeriveInput);
    variables(&input).unwrap_or_else(Error::into_compile_error).into()
}

/// Named components of a state vector (see `fmu_export::StateVector`).
///
/// ```
/// use fmu_export::StateVector;
///
/// /// The state vector.
/// #[derive(StateVector)]
/// pub struct State<T = f64> {
///     /// Angle
///     #[state(unit = "rad", display = "deg")]
///     pub theta: T,
///     /// Angular velocity
///     #[state(unit = "rad/s")]
///     pub omega: T,
/// }
///
/// assert_eq!((State::LEN, State::THETA, State::OMEGA), (2, 0, 1));
/// let x = [0.5, -1.0];
/// let State { theta, omega } = State::load(&x);
/// let mut dx = [0.0; State::LEN];
/// State { theta: omega, omega: -theta }.store(&mut dx);
/// assert_eq!(dx, [-1.0, -0.5]);
/// ```
#[proc_macro_derive(StateVector, attributes(state))]
pub fn derive_state_vector(input: TokenStream) -> TokenStream {
    let input = parse_macro_input!(input as DeriveInput);
    state_vector(&input).unwrap_or_else(Error::into_compile_error).into()
}

/// The named fields of a struct, or an error naming the derive.
fn named_fields<'a>(input: &'a DeriveInput, derive: &str) -> Result<Vec<&'a Field>> {
    match &input.data {
        Data::Struct(s) => match &s.fields {
            Fields::Named(named) => Ok(named.named.iter().collect()),
            _ => Err(Error::new(input.ident.span(), format!("#[derive({derive})] needs a struct with named fields"))),
        },
        _ => Err(Error::new(input.ident.span(), format!("#[derive({derive})] needs a struct"))),
    }
}

/// The doc comment of a field, its lines joined by spaces: the variable's description.
fn description(field: &Field) -> Result<String> {
    let mut lines = Vec::new();
    for attr in field.attrs.iter().filter(|a| a.path().is_ident("doc")) {
        if let syn::Meta::NameValue(nv) = &attr.meta {
            if let Expr::Lit(syn::ExprLit { lit: syn::Lit::Str(s), .. }) = &nv.value {
                let line = s.value();
                let line = line.trim();
                if !line.is_empty() {
                    lines.push(line.to_owned());
                }
            }
        }
    }
    if lines.is_empty() {
        let name = field.ident.as_ref().map(Ident::to_string).unwrap_or_default();
        return Err(Error::new(field.span(), format!("variable `{name}` needs a doc comment: it is the variable's description")));
    }
    Ok(lines.join(" "))
}

/// The value type of a variable field.
#[derive(Clone, Copy, PartialEq)]
enum ValueType {
    Real,
    /// A plane vector (`Vector2<T>`): two Real rows, `NAME_x` and `NAME_y`.
    Vector,
    Integer,
    Boolean,
    String,
}

/// The type parameter a model struct computes with: the one whose default is `f64`
/// (`struct Car<T = f64>`).
fn number_parameter(input: &DeriveInput) -> Option<Ident> {
    input.generics.type_params().find_map(|p| match &p.default {
        Some(Type::Path(d)) if d.path.is_ident("f64") => Some(p.ident.clone()),
        _ => None,
    })
}

/// True when `ty` is the number type `number` itself.
fn is_number(ty: &Type, number: Option<&Ident>) -> bool {
    matches!((ty, number), (Type::Path(p), Some(n)) if p.qself.is_none() && p.path.is_ident(n))
}

/// True when `ty` is `Vector2<N>` (any path ending so) of the number type `number`.
fn is_vector(ty: &Type, number: Option<&Ident>) -> bool {
    let Type::Path(p) = ty else { return false };
    let Some(last) = p.path.segments.last() else { return false };
    if last.ident != "Vector2" {
        return false;
    }
    match &last.arguments {
        syn::PathArguments::AngleBracketed(args) => {
            matches!(args.args.first(), Some(syn::GenericArgument::Type(t)) if args.args.len() == 1 && is_number(t, number))
        }
        _ => false,
    }
}

/// True when the tokens of `ty` name `number` anywhere (`Option<T>`, `Road<T>`).
fn mentions(ty: &Type, number: &Ident) -> bool {
    fn walk(tokens: Tokens, number: &Ident) -> bool {
        tokens.into_iter().any(|t| match t {
            proc_macro2::TokenTree::Ident(i) => i == *number,
            proc_macro2::TokenTree::Group(g) => walk(g.stream(), number),
            _ => false,
        })
    }
    walk(quote!(#ty), number)
}

/// `ty` with the number type written as `f64` (the layout tag of the simulated model).
fn as_f64(ty: &Type, number: Option<&Ident>) -> String {
    fn walk(tokens: Tokens, number: &Ident) -> Tokens {
        tokens
            .into_iter()
            .map(|t| match t {
                proc_macro2::TokenTree::Ident(i) if i == *number => proc_macro2::TokenTree::Ident(Ident::new("f64", i.span())),
                proc_macro2::TokenTree::Group(g) => {
                    let mut group = proc_macro2::Group::new(g.delimiter(), walk(g.stream(), number));
                    group.set_span(g.span());
                    proc_macro2::TokenTree::Group(group)
                }
                other => other,
            })
            .collect()
    }
    let tokens = match number {
        Some(n) => walk(quote!(#ty), n),
        None => quote!(#ty),
    };
    tokens.to_string().replace(' ', "")
}

fn value_type(ty: &Type, number: Option<&Ident>) -> Result<ValueType> {
    if is_number(ty, number) {
        return Ok(ValueType::Real);
    }
    if is_vector(ty, number) {
        return Ok(ValueType::Vector);
    }
    if let Type::Path(p) = ty {
        if p.qself.is_none() {
            if let Some(ident) = p.path.get_ident() {
                match ident.to_string().as_str() {
                    "f64" if number.is_none() => return Ok(ValueType::Real),
                    "f64" => {
                        let n = number.expect("checked");
                        return Err(Error::new(
                            ty.span(),
                            format!(
                                "a Real variable of a model generic over its number type is a `{n}` (its derivatives are computed with it)"
                            ),
                        ));
                    }
                    "i32" => return Ok(ValueType::Integer),
                    "bool" => return Ok(ValueType::Boolean),
                    "String" => return Ok(ValueType::String),
                    _ => {}
                }
            }
        }
    }
    let real = number.map_or("f64".to_owned(), Ident::to_string);
    Err(Error::new(
        ty.span(),
        format!("a variable field must be {real} (Real), Vector2<{real}> (two Real rows, NAME_x and NAME_y), i32 (Integer), bool (Boolean) or String (String)"),
    ))
}

#[derive(Clone, Copy, PartialEq)]
enum Kind {
    Parameter,
    Input,
    Output,
}

/// The accepted values of a parameter or input, as written in the attribute.
enum RangeSpec {
    Finite,
    Positive,
    NonNegative,
    Bounds { min: Option<Box<Expr>>, max: Option<Box<Expr>> },
    OneOf(Vec<Expr>),
}

/// Everything one field attribute says.
struct VariableSpec {
    kind: Kind,
    name: Option<LitStr>,
    unit: Option<LitStr>,
    display: Option<LitStr>,
    range: Option<RangeSpec>,
    discrete: bool,
    /// A parameter the importer may change after initialization (`variability="tunable"`).
    tunable: bool,
    /// An Integer output of another type than i32 (an enum of regimes): read with `Into<i32>`.
    integer: bool,
    when: Option<Expr>,
}

fn set_once<T>(slot: &mut Option<T>, value: T, span: Span, what: &str) -> Result<()> {
    if slot.is_some() {
        return Err(Error::new(span, format!("{what} is given twice")));
    }
    *slot = Some(value);
    Ok(())
}

fn set_range(spec: &mut Option<RangeSpec>, range: RangeSpec, span: Span) -> Result<()> {
    match (spec.as_mut(), range) {
        (None, range) => *spec = Some(range),
        // min and max may come as two keys.
        (Some(RangeSpec::Bounds { min, max }), RangeSpec::Bounds { min: new_min, max: new_max })
            if !(min.is_some() && new_min.is_some() || max.is_some() && new_max.is_some()) =>
        {
            if new_min.is_some() {
                *min = new_min;
            }
            if new_max.is_some() {
                *max = new_max;
            }
        }
        _ => return Err(Error::new(span, "a variable has one range: positive, non_negative, finite, min/max or one_of")),
    }
    Ok(())
}

fn variable_spec(field: &Field) -> Result<Option<VariableSpec>> {
    let mut found: Option<VariableSpec> = None;
    for attr in &field.attrs {
        let kind = if attr.path().is_ident("parameter") {
            Kind::Parameter
        } else if attr.path().is_ident("input") {
            Kind::Input
        } else if attr.path().is_ident("output") {
            Kind::Output
        } else {
            continue;
        };
        if found.is_some() {
            return Err(Error::new(attr.span(), "a field is one variable: give one of #[parameter], #[input] or #[output]"));
        }
        let mut spec = VariableSpec {
            kind,
            name: None,
            unit: None,
            display: None,
            range: None,
            discrete: false,
            tunable: false,
            integer: false,
            when: None,
        };
        if !matches!(attr.meta, syn::Meta::Path(_)) {
            attr.parse_nested_meta(|meta| {
                let span = meta.path.span();
                let key = meta.path.get_ident().map(Ident::to_string).unwrap_or_default();
                match key.as_str() {
                    "name" => set_once(&mut spec.name, meta.value()?.parse()?, span, "name"),
                    "unit" => set_once(&mut spec.unit, meta.value()?.parse()?, span, "unit"),
                    "display" => set_once(&mut spec.display, meta.value()?.parse()?, span, "display"),
                    "when" => set_once(&mut spec.when, meta.value()?.parse()?, span, "when"),
                    "discrete" => {
                        spec.discrete = true;
                        Ok(())
                    }
                    "tunable" => {
                        spec.tunable = true;
                        Ok(())
                    }
                    "integer" => {
                        spec.integer = true;
                        Ok(())
                    }
                    "finite" => set_range(&mut spec.range, RangeSpec::Finite, span),
                    "positive" => set_range(&mut spec.range, RangeSpec::Positive, span),
                    "non_negative" => set_range(&mut spec.range, RangeSpec::NonNegative, span),
                    "min" => set_range(&mut spec.range, RangeSpec::Bounds { min: Some(Box::new(meta.value()?.parse()?)), max: None }, span),
                    "max" => set_range(&mut spec.range, RangeSpec::Bounds { min: None, max: Some(Box::new(meta.value()?.parse()?)) }, span),
                    "one_of" => {
                        let content;
                        syn::parenthesized!(content in meta.input);
                        let values = content.parse_terminated(Expr::parse, syn::Token![,])?;
                        set_range(&mut spec.range, RangeSpec::OneOf(values.into_iter().collect()), span)
                    }
                    _ => Err(meta.error(
                        "unknown key: expected name, unit, display, positive, non_negative, finite, min, max, one_of, discrete, tunable, integer or when",
                    )),
                }
            })?;
        }
        found = Some(spec);
    }
    Ok(found)
}

/// The builder expressions of the rows of one field (two for a vector), given the number
/// `k` of its first real field ([`fmu_export::Lift::field`]).
fn rows(field: &Field, spec: &VariableSpec, number: Option<&Ident>, k: usize) -> Result<Vec<Tokens>> {
    let ident = field.ident.as_ref().expect("named field");
    let name = spec.name.as_ref().map(LitStr::value).unwrap_or_else(|| ident.to_string());
    let desc = description(field)?;
    let err = |what: &str| Err(Error::new(field.span(), format!("`{name}`: {what}")));
    let ty = if spec.integer {
        if spec.kind != Kind::Output {
            return err("only outputs take `integer` (an enum read as its number)");
        }
        ValueType::Integer
    } else {
        value_type(&field.ty, number)?
    };
    let v = quote!(::fmu_export::Variable::<Self>);
    // A lifted model's real fields are numbered in declaration order (see `lift_impl`).
    let field_no = |row: Tokens, k: usize| if number.is_some() { quote!(#row.field(#k)) } else { row };
    let mut built = match (spec.kind, ty) {
        (Kind::Parameter, ValueType::Real) => vec![field_no(quote!(#v::parameter(#name, #desc, |m| m.#ident, |m, v| m.#ident = v)), k)],
        (Kind::Parameter, ValueType::Integer) => vec![quote!(#v::integer_parameter(#name, #desc, |m| m.#ident, |m, v| m.#ident = v))],
        (Kind::Parameter, ValueType::Boolean) => vec![quote!(#v::boolean_parameter(#name, #desc, |m| m.#ident, |m, v| m.#ident = v))],
        (Kind::Parameter, ValueType::String) => {
            vec![quote!(#v::string_parameter(#name, #desc, |m| m.#ident.as_str(), |m, v| m.#ident = ::std::string::String::from(v)))]
        }
        (Kind::Input, ValueType::Real) => vec![field_no(quote!(#v::input(#name, #desc, |m| m.#ident, |m, v| m.#ident = v)), k)],
        (Kind::Input, _) => return err("inputs are Real"),
        (Kind::Output, ValueType::Real) if spec.discrete => vec![field_no(quote!(#v::discrete_output(#name, #desc, |m| m.#ident)), k)],
        (Kind::Output, ValueType::Real) => vec![field_no(quote!(#v::output(#name, #desc, |m| m.#ident)), k)],
        (Kind::Output, ValueType::Vector) => {
            // "x and y of the joint A" becomes "x of the joint A" and "y of the joint A".
            let Some(rest) = desc.strip_prefix("x and y ") else {
                return err("the doc comment of a vector output starts with \"x and y \" (\"x and y of the joint A\")");
            };
            let (name_x, name_y) = (format!("{name}_x"), format!("{name}_y"));
            let (desc_x, desc_y) = (format!("x {rest}"), format!("y {rest}"));
            let make = if spec.discrete { quote!(discrete_output) } else { quote!(output) };
            vec![
                field_no(quote!(#v::#make(#name_x, #desc_x, |m| m.#ident.x)), k),
                field_no(quote!(#v::#make(#name_y, #desc_y, |m| m.#ident.y)), k + 1),
            ]
        }
        (Kind::Output, ValueType::Integer) if spec.integer => {
            vec![quote!(#v::integer_output(#name, #desc, |m| ::std::convert::Into::<i32>::into(m.#ident)))]
        }
        (Kind::Output, ValueType::Integer) => vec![quote!(#v::integer_output(#name, #desc, |m| m.#ident))],
        (Kind::Output, ValueType::Boolean) => vec![quote!(#v::boolean_output(#name, #desc, |m| m.#ident))],
        (Kind::Output, ValueType::String) => return err("String variables are parameters"),
        (_, ValueType::Vector) => return err("vectors are outputs (their rows NAME_x and NAME_y)"),
    };
    if spec.discrete && !(spec.kind == Kind::Output && matches!(ty, ValueType::Real | ValueType::Vector)) {
        return err("only Real outputs take `discrete` (Integer and Boolean outputs always are)");
    }
    let mut modifiers = Vec::new();
    if spec.tunable {
        if spec.kind != Kind::Parameter {
            return err("only parameters take `tunable` (inputs can always be set)");
        }
        modifiers.push(quote!(.variability(::fmu_export::Variability::Tunable)));
    }
    if let Some(unit) = &spec.unit {
        modifiers.push(quote!(.unit(#unit)));
    }
    if let Some(display) = &spec.display {
        modifiers.push(quote!(.display(#display)));
    }
    if let Some(range) = &spec.range {
        if spec.kind == Kind::Output {
            return err("outputs have no range: the toolkit checks what the importer sets");
        }
        let range = match (range, ty) {
            (RangeSpec::Finite, ValueType::Real) => quote!(::fmu_export::Range::Finite),
            (RangeSpec::Positive, ValueType::Real) => quote!(::fmu_export::Range::Positive),
            (RangeSpec::NonNegative, ValueType::Real) => quote!(::fmu_export::Range::NonNegative),
            (RangeSpec::Bounds { min, max }, ValueType::Real | ValueType::Integer) => {
                let bound = |b: &Option<Box<Expr>>| match b {
                    Some(e) => quote!(::std::option::Option::Some((#e) as f64)),
                    None => quote!(::std::option::Option::None),
                };
                let (min, max) = (bound(min), bound(max));
                quote!(::fmu_export::Range::Bounds { min: #min, max: #max })
            }
            (RangeSpec::OneOf(values), ValueType::Integer) => quote!(::fmu_export::Range::OneOf(&[#(#values),*])),
            (RangeSpec::OneOf(_), _) => return err("one_of is for Integer (i32) variables"),
            (_, ValueType::Integer) => return err("an Integer variable takes min, max or one_of"),
            (_, ValueType::Boolean) => return err("a Boolean variable has no range"),
            (_, ValueType::String) => return err("a String variable has no range"),
            (_, ValueType::Vector) => unreachable!("vectors are outputs"),
        };
        modifiers.push(quote!(.range(#range)));
    }
    for row in &mut built {
        *row = quote!(#row #(#modifiers)*);
    }
    Ok(built)
}

/// `#[variables(states = S, bound = "...")]` on the struct.
fn struct_options(input: &DeriveInput) -> Result<(Option<Type>, Vec<WherePredicate>)> {
    let (mut states, mut bounds) = (None, Vec::new());
    for attr in input.attrs.iter().filter(|a| a.path().is_ident("variables")) {
        attr.parse_nested_meta(|meta| {
            if meta.path.is_ident("states") {
                set_once(&mut states, meta.value()?.parse()?, meta.path.span(), "states")
            } else if meta.path.is_ident("bound") {
                let text: LitStr = meta.value()?.parse()?;
                let parsed = text.parse_with(syn::punctuated::Punctuated::<WherePredicate, syn::Token![,]>::parse_terminated)?;
                bounds.extend(parsed);
                Ok(())
            } else {
                Err(meta.error("unknown key: expected states = StateType or bound = \"P: Trait\""))
            }
        })?;
    }
    Ok((states, bounds))
}

/// The generics of an impl for the struct with its number type `number` set to `as_type`:
/// (the impl's parameters and where clause, the struct's arguments).
fn with_number(input: &DeriveInput, number: Option<&Ident>, as_type: &Tokens, bounds: &[WherePredicate]) -> (Tokens, Tokens, Tokens) {
    let mut generics = input.generics.clone();
    generics.make_where_clause().predicates.extend(bounds.iter().cloned());
    let mut params = Vec::new();
    let mut args = Vec::new();
    for param in &generics.params {
        match param {
            syn::GenericParam::Type(t) if Some(&t.ident) == number => args.push(as_type.clone()),
            syn::GenericParam::Type(t) => {
                let (ident, bounds) = (&t.ident, &t.bounds);
                params.push(if bounds.is_empty() { quote!(#ident) } else { quote!(#ident: #bounds) });
                args.push(quote!(#ident));
            }
            syn::GenericParam::Lifetime(l) => {
                let lifetime = &l.lifetime;
                params.push(quote!(#l));
                args.push(quote!(#lifetime));
            }
            syn::GenericParam::Const(c) => {
                let ident = &c.ident;
                params.push(quote!(#c));
                args.push(quote!(#ident));
            }
        }
    }
    let where_clause = &generics.where_clause;
    (quote!(<#(#params),*>), quote!(<#(#args),*> #where_clause), quote!(<#(#args),*>))
}

fn variables(input: &DeriveInput) -> Result<Tokens> {
    let ident = &input.ident;
    let (states, bounds) = struct_options(input)?;
    let number = number_parameter(input);
    let number = number.as_ref();
    let (impl_params, ty_args_where, _) = with_number(input, number, &quote!(f64), &bounds);

    let mut body = Vec::new();
    let mut states_placed = false;
    let mut names: Vec<(String, Span)> = Vec::new();
    let fields = named_fields(input, "Variables")?;
    let layout: Vec<String> = fields.iter().map(|f| format!("{}: {}", f.ident.as_ref().expect("named"), as_f64(&f.ty, number))).collect();
    let layout = layout.join("; ");
    // The real fields of the struct in declaration order, as a lifted model numbers them.
    let mut real_fields: Vec<Tokens> = Vec::new();
    let mut capacity = 0usize;
    for field in &fields {
        let field_ident = field.ident.as_ref().expect("named");
        let spec = variable_spec(field)?;
        let k = real_fields.len();
        if is_number(&field.ty, number) {
            real_fields.push(quote!(#field_ident));
        } else if is_vector(&field.ty, number) {
            real_fields.push(quote!(#field_ident.x));
            real_fields.push(quote!(#field_ident.y));
        }
        let Some(spec) = spec else { continue };
        if field.attrs.iter().any(|a| a.path().is_ident("derived")) {
            return Err(Error::new(field.span(), "a #[derived] field is computed by the toolkit, not a variable"));
        }
        let built = rows(field, &spec, number, k)?;
        let base = spec.name.as_ref().map(LitStr::value).unwrap_or_else(|| field_ident.to_string());
        let row_names: Vec<String> = if built.len() == 2 { vec![format!("{base}_x"), format!("{base}_y")] } else { vec![base] };
        for name in row_names {
            if names.iter().any(|(n, _)| *n == name) {
                return Err(Error::new(field.span(), format!("variable name `{name}` is used twice")));
            }
            names.push((name, field.span()));
        }
        if spec.kind == Kind::Output && !states_placed {
            // The states come after the parameters and inputs, before the first output.
            body.push(quote!(let states_at = rows.len();));
            states_placed = true;
        }
        capacity += built.len();
        for row in built {
            body.push(match &spec.when {
                Some(condition) => quote!(if #condition { rows.push(#row); }),
                None => quote!(rows.push(#row);),
            });
        }
    }
    if !states_placed {
        body.push(quote!(let states_at = rows.len();));
    }
    let finish = match states {
        Some(states) => {
            quote!(::fmu_export::model::place_states(rows, states_at, <#states as ::fmu_export::StateVector>::variables::<Self>()))
        }
        None => quote!({
            let _ = states_at;
            rows
        }),
    };
    let (lift, lifting) = match number {
        Some(n) => (
            lift_impl(input, &fields, n, &bounds, &real_fields)?,
            quote! {
                fn lifting() -> ::std::option::Option<::fmu_export::model::Lifting<Self>> {
                    ::std::option::Option::Some(::fmu_export::model::Lifting {
                        refresh: <Self as ::fmu_export::Lift>::refresh,
                        derived_current: <Self as ::fmu_export::Lift>::derived_current,
                        forward: ::fmu_export::core::derivatives::forward::<Self>,
                        states: ::fmu_export::core::derivatives::states::<Self>,
                        trajectory: ::fmu_export::core::derivatives::trajectory::<Self>,
                    })
                }
            },
        ),
        None => (quote!(), quote!()),
    };
    Ok(quote! {
        impl #impl_params ::fmu_export::Variables for #ident #ty_args_where {
            const LAYOUT: &'static str = #layout;

            fn variables() -> ::std::vec::Vec<::fmu_export::Variable<Self>> {
                let mut rows: ::std::vec::Vec<::fmu_export::Variable<Self>> = ::std::vec::Vec::with_capacity(#capacity);
                #(#body)*
                #finish
            }

            #lifting
        }

        #lift
    })
}

/// `impl Lift` for a struct generic over its number type `number`: the lifted copy (real
/// fields converted, `#[derived]` fields computed again, the rest cloned), the numbered real
/// fields, and the refresh and check of the derived fields.
fn lift_impl(input: &DeriveInput, fields: &[&Field], number: &Ident, bounds: &[WherePredicate], real_fields: &[Tokens]) -> Result<Tokens> {
    let ident = &input.ident;
    let (impl_params, ty_args_where, _) = with_number(input, Some(number), &quote!(f64), bounds);
    let (_, _, over_args) = with_number(input, Some(number), &quote!(U), bounds);
    let mut inits = Vec::new();
    let mut derived = Vec::new();
    for field in fields {
        let f = field.ident.as_ref().expect("named");
        if field.attrs.iter().any(|a| a.path().is_ident("derived")) {
            inits.push(quote!(#f: ::std::default::Default::default()));
            derived.push(f.clone());
        } else if is_number(&field.ty, Some(number)) {
            inits.push(quote!(#f: <U as ::std::convert::From<f64>>::from(self.#f)));
        } else if is_vector(&field.ty, Some(number)) {
            inits.push(quote!(#f: ::fmu_export::nalgebra::Vector2::new(
                <U as ::std::convert::From<f64>>::from(self.#f.x),
                <U as ::std::convert::From<f64>>::from(self.#f.y),
            )));
        } else if mentions(&field.ty, number) {
            return Err(Error::new(
                field.ty.span(),
                format!("a field whose type holds the number type `{number}` is `{number}`, `Vector2<{number}>`, or #[derived] from the parameters"),
            ));
        } else {
            inits.push(quote!(#f: ::std::clone::Clone::clone(&self.#f)));
        }
    }
    let arms = real_fields.iter().enumerate().map(|(k, path)| quote!(#k => &mut model.#path,));
    Ok(quote! {
        impl #impl_params ::fmu_export::Lift for #ident #ty_args_where {
            type Over<U: ::fmu_export::Scalar> = #ident #over_args;

            fn lift<U: ::fmu_export::Scalar>(&self) -> Self::Over<U> {
                #[allow(unused_mut)]
                let mut lifted: Self::Over<U> = #ident { #(#inits),* };
                <Self as ::fmu_export::Lift>::refresh_over::<U>(&mut lifted);
                lifted
            }

            fn refresh_over<U: ::fmu_export::Scalar>(model: &mut Self::Over<U>) {
                let _ = &model;
                #(model.#derived = ::fmu_export::Derived::of(&*model);)*
            }

            fn field<U: ::fmu_export::Scalar>(model: &mut Self::Over<U>, k: usize) -> &mut U {
                match k {
                    #(#arms)*
                    _ => panic!("{} has no real field number {k}", stringify!(#ident)),
                }
            }

            fn refresh(&mut self) {
                #(self.#derived = ::fmu_export::Derived::of(&*self);)*
            }

            fn derived_current(&self) -> bool {
                true #(&& ::fmu_export::model::is_current(&self.#derived, self))*
            }
        }
    })
}

fn state_vector(input: &DeriveInput) -> Result<Tokens> {
    let ident = &input.ident;
    // One type parameter at most: the number type (`struct State<T = f64>`).
    let number = number_parameter(input);
    if input.generics.params.len() > usize::from(number.is_some()) {
        return Err(Error::new(
            input.generics.span(),
            "#[derive(StateVector)] needs a struct whose only generic parameter is its number type (`struct State<T = f64>`)",
        ));
    }
    let number = number.as_ref();
    let fields = named_fields(input, "StateVector")?;
    let (mut consts, mut loads, mut stores, mut rows) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for (i, field) in fields.iter().enumerate() {
        let field_ident = field.ident.as_ref().expect("named field");
        if value_type(&field.ty, number)? != ValueType::Real {
            let real = number.map_or("f64".to_owned(), Ident::to_string);
            return Err(Error::new(field.ty.span(), format!("a state is a Real: every field of a state vector is {real}")));
        }
        let (mut name, mut unit, mut display, mut after): (Option<LitStr>, Option<LitStr>, Option<LitStr>, Option<LitStr>) =
            (None, None, None, None);
        for attr in field.attrs.iter().filter(|a| a.path().is_ident("state")) {
            attr.parse_nested_meta(|meta| {
                let span = meta.path.span();
                let key = meta.path.get_ident().map(Ident::to_string).unwrap_or_default();
                match key.as_str() {
                    "name" => set_once(&mut name, meta.value()?.parse()?, span, "name"),
                    "unit" => set_once(&mut unit, meta.value()?.parse()?, span, "unit"),
                    "display" => set_once(&mut display, meta.value()?.parse()?, span, "display"),
                    "after" => set_once(&mut after, meta.value()?.parse()?, span, "after"),
                    _ => Err(meta.error("unknown key: expected name, unit, display or after")),
                }
            })?;
        }
        let name = name.map(|n| n.value()).unwrap_or_else(|| field_ident.to_string());
        let desc = description(field)?;
        let index_const = format_ident!("{}", field_ident.to_string().to_uppercase(), span = field_ident.span());
        let doc = format!("Index of `{field_ident}` in the state vector.");
        consts.push(quote!(#[doc = #doc] pub const #index_const: usize = #i;));
        loads.push(quote!(#field_ident: x[#i]));
        stores.push(quote!(x[#i] = self.#field_ident;));
        let mut row = quote!(::fmu_export::Variable::<M>::state(#name, #desc, #i));
        if let Some(unit) = unit {
            row = quote!(#row.unit(#unit));
        }
        if let Some(display) = display {
            row = quote!(#row.display(#display));
        }
        let after = match after {
            Some(a) => quote!(::std::option::Option::Some(#a)),
            None => quote!(::std::option::Option::None),
        };
        rows.push(quote!(::fmu_export::StateVariable { variable: #row, after: #after }));
    }
    let len = fields.len();
    // The number type's parameter of the load/store impl, and the f64 struct for the rest.
    let (load_params, load_ty, f64_ty) = match number {
        Some(n) => (quote!(<#n: ::std::marker::Copy>), quote!(#ident<#n>), quote!(#ident<f64>)),
        None => (quote!(), quote!(#ident), quote!(#ident)),
    };
    let element = match number {
        Some(n) => quote!(#n),
        None => quote!(f64),
    };
    Ok(quote! {
        // A model may use only some of these (the table rows alone, or slices with the indices).
        #[allow(dead_code)]
        impl #f64_ty {
            /// Number of components of the state vector.
            pub const LEN: usize = #len;
            #(#consts)*
        }

        #[allow(dead_code)]
        impl #load_params #load_ty {
            /// The components of the state vector `x`.
            #[inline(always)]
            pub fn load(x: &[#element]) -> #load_ty {
                #ident { #(#loads),* }
            }

            /// Writes the components into the state vector (or its time derivative) `x`.
            #[inline(always)]
            pub fn store(&self, x: &mut [#element]) {
                #(#stores)*
            }
        }

        impl ::fmu_export::StateVector for #f64_ty {
            const LEN: usize = #len;

            fn variables<M>() -> ::std::vec::Vec<::fmu_export::StateVariable<M>> {
                ::std::vec![#(#rows),*]
            }
        }
    })
}
