//! Strict key checking for the toolkit's input files (model and FRD JSON, manifests, testbed and
//! loopshaping configs): an unknown key is an error that names the key, where it is, and the
//! closest allowed key, instead of being ignored.
//!
//! "Closest" is the edit distance between the lower-cased keys (insertions, deletions,
//! substitutions and swaps of neighbours, each 1: the optimal-string-alignment form of the
//! Damerau–Levenshtein distance), suggested when it is at most `max(1, len/3)` or when one key
//! (of three characters or more) begins the other (`freq` for `freq_hz`); known aliases of other tools (`dt`, `Ts` for `ts`) are
//! suggested by name.

/// The number of single-character edits (insertion, deletion, substitution, transposition of
/// two neighbours) between `a` and `b`: the optimal-string-alignment distance, O(|a|·|b|).
pub fn edit_distance(a: &str, b: &str) -> usize {
    let (a, b): (Vec<char>, Vec<char>) = (a.chars().collect(), b.chars().collect());
    let w = b.len() + 1;
    let mut d = vec![0usize; (a.len() + 1) * w];
    for i in 0..=a.len() {
        for j in 0..=b.len() {
            d[i * w + j] = if i == 0 || j == 0 {
                i + j
            } else {
                let sub = d[(i - 1) * w + j - 1] + usize::from(a[i - 1] != b[j - 1]);
                let mut best = sub.min(d[(i - 1) * w + j] + 1).min(d[i * w + j - 1] + 1);
                if i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1] {
                    best = best.min(d[(i - 2) * w + j - 2] + 1);
                }
                best
            };
        }
    }
    d[a.len() * w + b.len()]
}

/// The allowed key closest to `key` (see the [module](self) docs), if any is close enough.
pub fn closest<'a>(key: &str, allowed: &[&'a str], aliases: &[(&str, &'a str)]) -> Option<&'a str> {
    if let Some((_, to)) = aliases.iter().find(|(from, _)| *from == key) {
        return Some(to);
    }
    let lower = key.to_lowercase();
    let limit = (lower.chars().count() / 3).max(1);
    allowed
        .iter()
        .map(|&a| {
            let al = a.to_lowercase();
            // a key cut short or run on (`freq` for `freq_hz`) is close whatever its length
            let prefix = lower.len().min(al.len()) >= 3
                && (al.starts_with(&lower) || lower.starts_with(&al));
            let d = edit_distance(&lower, &al);
            (if prefix { d.min(limit) } else { d }, a)
        })
        .filter(|&(d, _)| d <= limit)
        .min_by_key(|&(d, _)| d)
        .map(|(_, a)| a)
}

/// `Err(message)` for the first key not in `allowed`: "unknown key `x` in PLACE: did you mean
/// `y`? (allowed: …)". `place` says where, e.g. "the manifest's experiment 2 (`fast`)".
///
/// # Errors
/// The message above, for the caller to wrap in its crate's error type.
pub fn check_keys<'k>(
    keys: impl IntoIterator<Item = &'k str>,
    allowed: &[&str],
    aliases: &[(&str, &str)],
    place: &str,
) -> std::result::Result<(), String> {
    for key in keys {
        if allowed.contains(&key) {
            continue;
        }
        let hint = match closest(key, allowed, aliases) {
            Some(c) => format!("did you mean `{c}`? "),
            None => String::new(),
        };
        return Err(format!(
            "unknown key `{key}` in {place}: {hint}(allowed: {})",
            allowed.join(", ")
        ));
    }
    Ok(())
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn distances() {
        assert_eq!(edit_distance("kitten", "sitting"), 3);
        assert_eq!(edit_distance("", "abc"), 3);
        assert_eq!(edit_distance("hold_dealy", "hold_delay"), 1);
        assert_eq!(edit_distance("nmae", "name"), 1);
        assert_eq!(edit_distance("ca", "abc"), 3);
    }

    #[test]
    fn suggestions() {
        let allowed = ["name", "file", "period_samples", "skip_periods", "role"];
        assert_eq!(
            closest("perod_samples", &allowed, &[]),
            Some("period_samples")
        );
        assert_eq!(closest("Role", &allowed, &[]), Some("role"));
        assert_eq!(closest("skip_period", &allowed, &[]), Some("skip_periods"));
        assert_eq!(closest("frequency", &allowed, &[]), None);
        assert_eq!(closest("freq", &["freq_hz", "re"], &[]), Some("freq_hz"));
        let model = ["type", "ts", "a", "b", "c", "d"];
        assert_eq!(closest("dt", &model, &[("dt", "ts")]), Some("ts"));
        assert_eq!(closest("Ts", &model, &[]), Some("ts"));
    }

    #[test]
    fn message_names_key_place_and_hint() {
        let e = check_keys(["name", "rol"], &["name", "role"], &[], "experiment 1").unwrap_err();
        assert_eq!(
            e,
            "unknown key `rol` in experiment 1: did you mean `role`? (allowed: name, role)"
        );
        assert!(check_keys(["name"], &["name"], &[], "x").is_ok());
    }
}
