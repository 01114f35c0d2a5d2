//! Text specs: `name` or `name:key=value,key=value`.

use std::collections::BTreeMap;
use std::fmt;
use std::str::FromStr;

use super::SpecError;

/// A parsed spec: a name and its parameters.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Spec {
    /// Provider or solver name.
    pub name: String,
    /// Parameters in key order.
    pub params: BTreeMap<String, String>,
}

impl FromStr for Spec {
    type Err = SpecError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let bad = |reason: &str| SpecError::MalformedSpec {
            spec: s.to_string(),
            reason: reason.to_string(),
        };
        let s_trim = s.trim();
        let (name, rest) = match s_trim.split_once(':') {
            Some((n, r)) => (n.trim(), Some(r)),
            None => (s_trim, None),
        };
        if name.is_empty() {
            return Err(bad("empty name"));
        }
        if !name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-' || c == '.')
        {
            return Err(bad(
                "name may only contain letters, digits, '_', '-' and '.'",
            ));
        }
        let mut params = BTreeMap::new();
        if let Some(rest) = rest {
            if rest.trim().is_empty() {
                return Err(bad("':' must be followed by key=value parameters"));
            }
            for kv in rest.split(',') {
                let (k, v) = kv
                    .split_once('=')
                    .ok_or_else(|| bad("parameters must be key=value"))?;
                let (k, v) = (k.trim(), v.trim());
                if k.is_empty() || v.is_empty() {
                    return Err(bad("empty parameter key or value"));
                }
                if params.insert(k.to_string(), v.to_string()).is_some() {
                    return Err(bad("parameter given twice"));
                }
            }
        }
        Ok(Spec {
            name: name.to_string(),
            params,
        })
    }
}

impl fmt::Display for Spec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.name)?;
        for (i, (k, v)) in self.params.iter().enumerate() {
            write!(f, "{}{k}={v}", if i == 0 { ':' } else { ',' })?;
        }
        Ok(())
    }
}

/// Splits a comma-separated list of specs. A comma also separates parameters, so a
/// piece of the form `key=value` without a `:` continues the previous spec:
/// `copy,grid:res=0.125,h=0.25,builtin` → `copy`, `grid:res=0.125,h=0.25`, `builtin`.
pub fn split_spec_list(list: &str) -> Result<Vec<Spec>, SpecError> {
    let mut out: Vec<String> = Vec::new();
    for piece in list.split(',') {
        let piece = piece.trim();
        if piece.is_empty() {
            continue;
        }
        if piece.contains('=') && !piece.contains(':') {
            match out.last_mut() {
                Some(prev) if prev.contains(':') => {
                    prev.push(',');
                    prev.push_str(piece);
                }
                _ => {
                    return Err(SpecError::MalformedSpec {
                        spec: piece.to_string(),
                        reason: "parameter without a provider (write name:key=value)".into(),
                    });
                }
            }
        } else {
            out.push(piece.to_string());
        }
    }
    out.iter().map(|s| s.parse()).collect()
}

/// Typed access to a spec's parameters; [`Params::finish`] rejects parameters nobody read.
#[derive(Debug)]
pub struct Params<'a> {
    spec: &'a Spec,
    accepted: Vec<&'static str>,
}

impl<'a> Params<'a> {
    /// Wraps a spec.
    pub fn new(spec: &'a Spec) -> Self {
        Self {
            spec,
            accepted: Vec::new(),
        }
    }

    /// The spec's name.
    pub fn name(&self) -> &str {
        &self.spec.name
    }

    /// The error for parameter `key` given as `value`, rejected for `reason`.
    pub fn invalid(&self, key: &str, value: &str, reason: impl Into<String>) -> SpecError {
        SpecError::InvalidParameter {
            spec: self.spec.name.clone(),
            param: key.to_string(),
            value: value.to_string(),
            reason: reason.into(),
        }
    }

    /// A raw string parameter.
    pub fn string(&mut self, key: &'static str) -> Option<&'a str> {
        self.accepted.push(key);
        self.spec.params.get(key).map(String::as_str)
    }

    /// A parameter that must be one of `options`; `None` when absent.
    pub fn choice(
        &mut self,
        key: &'static str,
        options: &[&str],
    ) -> Result<Option<&'a str>, SpecError> {
        match self.string(key) {
            None => Ok(None),
            Some(v) if options.contains(&v) => Ok(Some(v)),
            Some(v) => Err(self.invalid(key, v, format!("must be one of {}", options.join(", ")))),
        }
    }

    /// A finite float parameter, or `default`.
    pub fn f64(&mut self, key: &'static str, default: f64) -> Result<f64, SpecError> {
        match self.string(key) {
            None => Ok(default),
            Some(v) => match v.parse::<f64>() {
                Ok(x) if x.is_finite() => Ok(x),
                Ok(_) => Err(self.invalid(key, v, "must be finite")),
                Err(e) => Err(self.invalid(key, v, e.to_string())),
            },
        }
    }

    /// A boolean parameter (`true` / `false`), or `default`.
    pub fn bool(&mut self, key: &'static str, default: bool) -> Result<bool, SpecError> {
        match self.string(key) {
            None => Ok(default),
            Some("true") => Ok(true),
            Some("false") => Ok(false),
            Some(v) => Err(self.invalid(key, v, "must be true or false")),
        }
    }

    /// An unsigned integer parameter, or `default`.
    pub fn u64(&mut self, key: &'static str, default: u64) -> Result<u64, SpecError> {
        match self.string(key) {
            None => Ok(default),
            Some(v) => v
                .parse::<u64>()
                .map_err(|e| self.invalid(key, v, e.to_string())),
        }
    }

    /// Errors if a parameter was given that no accessor asked for.
    pub fn finish(self) -> Result<(), SpecError> {
        for k in self.spec.params.keys() {
            if !self.accepted.contains(&k.as_str()) {
                let mut acc = self.accepted.clone();
                acc.sort_unstable();
                acc.dedup();
                return Err(SpecError::UnknownParameter {
                    spec: self.spec.name.clone(),
                    param: k.clone(),
                    accepted: if acc.is_empty() {
                        "none".into()
                    } else {
                        acc.join(", ")
                    },
                });
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_names_and_params() {
        let s: Spec = "random:seed=3,lo=0".parse().unwrap();
        assert_eq!(s.name, "random");
        assert_eq!(s.params["seed"], "3");
        assert_eq!(s.to_string(), "random:lo=0,seed=3");
        assert!("".parse::<Spec>().is_err());
        assert!("bad:".parse::<Spec>().is_err());
        assert!("bad:value".parse::<Spec>().is_err());
        assert!("bad:value=1,value=2".parse::<Spec>().is_err());
    }

    #[test]
    fn list_attaches_parameters_to_previous_spec() {
        let v = split_spec_list("copy,grid:res=0.125,h=0.25,builtin").unwrap();
        let names: Vec<_> = v.iter().map(|s| s.to_string()).collect();
        assert_eq!(names, ["copy", "grid:h=0.25,res=0.125", "builtin"]);
        assert!(split_spec_list("h=0.25,copy").is_err());
    }
}
