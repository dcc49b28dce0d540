//! Variable names under FMI 2.0 `variableNamingConvention="structured"`:
//!
//! ```text
//! name         = identifier | "der(" identifier ["," unsignedInteger] ")"
//! identifier   = bname [arrayIndices] {"." bname [arrayIndices]}
//! bname        = nondigit {digit | nondigit} | qname
//! qname        = "'" (qchar | escape) {qchar | escape} "'"
//! arrayIndices = "[" unsignedInteger {"," unsignedInteger} "]"
//! ```

fn is_nondigit(c: char) -> bool {
    c == '_' || c.is_ascii_alphabetic()
}

fn is_qchar(c: char) -> bool {
    is_nondigit(c) || c.is_ascii_digit() || "!#$%&()*+,-./:;<>=?@[]^{}|~ ".contains(c)
}

fn is_escaped(c: char) -> bool {
    "'\"?\\abfnrtv".contains(c)
}

/// Position after the digits at `i`, if there is at least one.
fn digits(c: &[char], mut i: usize) -> Option<usize> {
    let start = i;
    while c.get(i).is_some_and(char::is_ascii_digit) {
        i += 1;
    }
    (i > start).then_some(i)
}

fn qname(c: &[char], mut i: usize) -> Option<usize> {
    i += 1; // opening quote
    let start = i;
    loop {
        match *c.get(i)? {
            '\'' => return (i > start).then_some(i + 1),
            '\\' if c.get(i + 1).copied().is_some_and(is_escaped) => i += 2,
            ch if is_qchar(ch) => i += 1,
            _ => return None,
        }
    }
}

fn bname(c: &[char], i: usize) -> Option<usize> {
    match *c.get(i)? {
        '\'' => qname(c, i),
        ch if is_nondigit(ch) => {
            let mut j = i + 1;
            while c
                .get(j)
                .is_some_and(|&ch| is_nondigit(ch) || ch.is_ascii_digit())
            {
                j += 1;
            }
            Some(j)
        }
        _ => None,
    }
}

fn array_indices(c: &[char], mut i: usize) -> Option<usize> {
    i += 1; // '['
    loop {
        i = digits(c, i)?;
        match *c.get(i)? {
            ',' => i += 1,
            ']' => return Some(i + 1),
            _ => return None,
        }
    }
}

fn identifier(c: &[char], mut i: usize) -> Option<usize> {
    loop {
        i = bname(c, i)?;
        if c.get(i) == Some(&'[') {
            i = array_indices(c, i)?;
        }
        if c.get(i) == Some(&'.') {
            i += 1;
        } else {
            return Some(i);
        }
    }
}

/// Whether `name` is legal under the "structured" naming convention.
pub(crate) fn is_structured_name(name: &str) -> bool {
    let c: Vec<char> = name.chars().collect();
    let whole = |end: Option<usize>| end == Some(c.len());
    if whole(identifier(&c, 0)) {
        return true;
    }
    // Not an identifier; the only other form is der(...).
    if !name.starts_with("der(") {
        return false;
    }
    let Some(mut i) = identifier(&c, 4) else {
        return false;
    };
    if c.get(i) == Some(&',') {
        match digits(&c, i + 1) {
            Some(j) => i = j,
            None => return false,
        }
    }
    c.get(i) == Some(&')') && i + 1 == c.len()
}

/// Whether `s` is a C identifier (the form `modelIdentifier` must have).
pub(crate) fn is_c_identifier(s: &str) -> bool {
    let mut chars = s.chars();
    chars.next().is_some_and(is_nondigit) && chars.all(|ch| is_nondigit(ch) || ch.is_ascii_digit())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn structured_names() {
        for ok in [
            "x",
            "_x1",
            "valve.u",
            "a.b.mod[3,4].'#123'.c",
            "'p A'",
            "'it\\'s'",
            "manifold.p[2]",
            "der(x)",
            "der(body.v,2)",
            "der('a b'.c[1])",
        ] {
            assert!(is_structured_name(ok), "{ok} rejected");
        }
        for bad in [
            "",
            "1x",
            "p A",
            "a..b",
            "a.",
            ".a",
            "a[]",
            "a[1,]",
            "a[x]",
            "''",
            "'unterminated",
            "der(x",
            "der(x,)",
            "der()",
            "der(x)y",
            "x-y",
            "é",
        ] {
            assert!(!is_structured_name(bad), "{bad} accepted");
        }
    }

    #[test]
    fn c_identifiers() {
        assert!(is_c_identifier("hydrobench_servovalve"));
        assert!(is_c_identifier("_a9"));
        assert!(!is_c_identifier(""));
        assert!(!is_c_identifier("9a"));
        assert!(!is_c_identifier("a-b"));
        assert!(!is_c_identifier("a.b"));
    }
}
