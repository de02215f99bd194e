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

/// The variable table of a model struct (see `fmu_export::Variables`).
#[proc_macro_derive(Variables, attributes(variables, parameter, input, output))]
pub fn derive_variables(input: TokenStream) -> TokenStream {
    let input = parse_macro_input!(input as DeriveInput);
    variables(&input).unwrap_or_else(Error::into_compile_error).into()
}

/// Named components of a state vector (see `fmu_export::StateVector`).
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
    Integer,
    Boolean,
    String,
}

fn value_type(ty: &Type) -> Result<ValueType> {
    if let Type::Path(p) = ty {
        if p.qself.is_none() {
            if let Some(ident) = p.path.get_ident() {
                match ident.to_string().as_str() {
                    "f64" => return Ok(ValueType::Real),
                    "i32" => return Ok(ValueType::Integer),
                    "bool" => return Ok(ValueType::Boolean),
                    "String" => return Ok(ValueType::String),
                    _ => {}
                }
            }
        }
    }
    Err(Error::new(ty.span(), "a variable field must be f64 (Real), i32 (Integer), bool (Boolean) or String (String)"))
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
        let mut spec =
            VariableSpec { kind, name: None, unit: None, display: None, range: None, discrete: false, tunable: false, when: None };
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
                        "unknown key: expected name, unit, display, positive, non_negative, finite, min, max, one_of, discrete, tunable or when",
                    )),
                }
            })?;
        }
        found = Some(spec);
    }
    Ok(found)
}

/// The builder expression of one row of the table.
fn row(field: &Field, spec: &VariableSpec) -> Result<Tokens> {
    let ident = field.ident.as_ref().expect("named field");
    let name = spec.name.as_ref().map(LitStr::value).unwrap_or_else(|| ident.to_string());
    let desc = description(field)?;
    let ty = value_type(&field.ty)?;
    let err = |what: &str| Err(Error::new(field.span(), format!("`{name}`: {what}")));
    let v = quote!(::fmu_export::Variable::<Self>);
    let mut row = match (spec.kind, ty) {
        (Kind::Parameter, ValueType::Real) => quote!(#v::parameter(#name, #desc, |m| m.#ident, |m, v| m.#ident = v)),
        (Kind::Parameter, ValueType::Integer) => quote!(#v::integer_parameter(#name, #desc, |m| m.#ident, |m, v| m.#ident = v)),
        (Kind::Parameter, ValueType::Boolean) => quote!(#v::boolean_parameter(#name, #desc, |m| m.#ident, |m, v| m.#ident = v)),
        (Kind::Parameter, ValueType::String) => {
            quote!(#v::string_parameter(#name, #desc, |m| m.#ident.as_str(), |m, v| m.#ident = ::std::string::String::from(v)))
        }
        (Kind::Input, ValueType::Real) => quote!(#v::input(#name, #desc, |m| m.#ident, |m, v| m.#ident = v)),
        (Kind::Input, _) => return err("inputs are Real (f64)"),
        (Kind::Output, ValueType::Real) if spec.discrete => quote!(#v::discrete_output(#name, #desc, |m| m.#ident)),
        (Kind::Output, ValueType::Real) => quote!(#v::output(#name, #desc, |m| m.#ident)),
        (Kind::Output, ValueType::Integer) => quote!(#v::integer_output(#name, #desc, |m| m.#ident)),
        (Kind::Output, ValueType::Boolean) => quote!(#v::boolean_output(#name, #desc, |m| m.#ident)),
        (Kind::Output, ValueType::String) => return err("String variables are parameters"),
    };
    if spec.discrete && !(spec.kind == Kind::Output && ty == ValueType::Real) {
        return err("only Real outputs take `discrete` (Integer and Boolean outputs always are)");
    }
    if spec.tunable {
        if spec.kind != Kind::Parameter {
            return err("only parameters take `tunable` (inputs can always be set)");
        }
        row = quote!(#row.variability(::fmu_export::Variability::Tunable));
    }
    if let Some(unit) = &spec.unit {
        row = quote!(#row.unit(#unit));
    }
    if let Some(display) = &spec.display {
        row = quote!(#row.display(#display));
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
        };
        row = quote!(#row.range(#range));
    }
    Ok(row)
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

fn variables(input: &DeriveInput) -> Result<Tokens> {
    let ident = &input.ident;
    let (states, bounds) = struct_options(input)?;
    let mut generics = input.generics.clone();
    generics.make_where_clause().predicates.extend(bounds);
    let (impl_generics, ty_generics, where_clause) = generics.split_for_impl();

    let mut body = Vec::new();
    let mut states_placed = false;
    let mut names: Vec<(String, Span)> = Vec::new();
    let fields = named_fields(input, "Variables")?;
    let layout: Vec<String> = fields
        .iter()
        .map(|f| {
            let ty = &f.ty;
            format!("{}: {}", f.ident.as_ref().expect("named"), quote!(#ty).to_string().replace(' ', ""))
        })
        .collect();
    let layout = layout.join("; ");
    for field in fields {
        let Some(spec) = variable_spec(field)? else { continue };
        let name = spec.name.as_ref().map(LitStr::value).unwrap_or_else(|| field.ident.as_ref().expect("named").to_string());
        if names.iter().any(|(n, _)| *n == name) {
            return Err(Error::new(field.span(), format!("variable name `{name}` is used twice")));
        }
        names.push((name, field.span()));
        if spec.kind == Kind::Output && !states_placed {
            // The states come after the parameters and inputs, before the first output.
            body.push(quote!(let states_at = rows.len();));
            states_placed = true;
        }
        let row = row(field, &spec)?;
        body.push(match &spec.when {
            Some(condition) => quote!(if #condition { rows.push(#row); }),
            None => quote!(rows.push(#row);),
        });
    }
    if !states_placed {
        body.push(quote!(let states_at = rows.len();));
    }
    // Room for every field's row at once (the table is built per instance and per check).
    let capacity = names.len();
    let finish = match states {
        Some(states) => {
            quote!(::fmu_export::model::place_states(rows, states_at, <#states as ::fmu_export::StateVector>::variables::<Self>()))
        }
        None => quote!({
            let _ = states_at;
            rows
        }),
    };
    Ok(quote! {
        impl #impl_generics ::fmu_export::Variables for #ident #ty_generics #where_clause {
            const LAYOUT: &'static str = #layout;

            fn variables() -> ::std::vec::Vec<::fmu_export::Variable<Self>> {
                let mut rows: ::std::vec::Vec<::fmu_export::Variable<Self>> = ::std::vec::Vec::with_capacity(#capacity);
                #(#body)*
                #finish
            }
        }
    })
}

fn state_vector(input: &DeriveInput) -> Result<Tokens> {
    let ident = &input.ident;
    if !input.generics.params.is_empty() {
        return Err(Error::new(input.generics.span(), "#[derive(StateVector)] needs a struct without generic parameters"));
    }
    let fields = named_fields(input, "StateVector")?;
    let (mut consts, mut loads, mut stores, mut rows) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for (i, field) in fields.iter().enumerate() {
        let field_ident = field.ident.as_ref().expect("named field");
        if value_type(&field.ty)? != ValueType::Real {
            return Err(Error::new(field.ty.span(), "a state is a Real: every field of a state vector is f64"));
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
    Ok(quote! {
        // A model may use only some of these (the table rows alone, or slices with the indices).
        #[allow(dead_code)]
        impl #ident {
            /// Number of components of the state vector.
            pub const LEN: usize = #len;
            #(#consts)*

            /// The components of the state vector `x`.
            #[inline(always)]
            pub fn load(x: &[f64]) -> #ident {
                #ident { #(#loads),* }
            }

            /// Writes the components into the state vector (or its time derivative) `x`.
            #[inline(always)]
            pub fn store(&self, x: &mut [f64]) {
                #(#stores)*
            }
        }

        impl ::fmu_export::StateVector for #ident {
            const LEN: usize = #len;

            fn variables<M>() -> ::std::vec::Vec<::fmu_export::StateVariable<M>> {
                ::std::vec![#(#rows),*]
            }
        }
    })
}
