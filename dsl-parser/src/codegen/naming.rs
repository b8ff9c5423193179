// Names derived from a model's text, without compiling it. Plain `std` code: the root
// build script includes this file as it is (`include!`) so that it need not build the
// compiler and its dependencies a second time as a build dependency.

/// The model name in `.dyn` text, found cheaply (the word after the first `model` outside
/// `#` and `//` comments), for the error stub of a model that does not compile.
pub fn model_name_hint(source: &str) -> Option<String> {
    let mut words = source
        .lines()
        .map(|l| {
            l.split("//")
                .next()
                .unwrap_or("")
                .split('#')
                .next()
                .unwrap_or("")
        })
        .flat_map(|l| l.split(|c: char| !(c.is_alphanumeric() || c == '_')))
        .filter(|w| !w.is_empty());
    while let Some(w) = words.next() {
        if w == "model" {
            return words.next().map(str::to_string);
        }
    }
    None
}

/// The Rust type name of a model: `two_mass` → `TwoMass`.
pub fn type_name(model: &str) -> String {
    let mut out = String::new();
    for part in model.split(|c: char| !c.is_ascii_alphanumeric()) {
        let mut chars = part.chars();
        if let Some(first) = chars.next() {
            out.push(first.to_ascii_uppercase());
            out.extend(chars);
        }
    }
    if out.is_empty() || out.starts_with(|c: char| c.is_ascii_digit()) {
        out.insert_str(0, "Model");
    }
    out
}
