//! `[render] antialias`: edge anti-aliasing (`docs/antialiasing.md`).

use serde::{Deserialize, Serialize};

/// `"off"`, `"edges"` (edge pixels get 4 to 16 sub-pixel rays, by their contrast), `4`, `8`
/// or `16` (every edge pixel gets that many), or `"reference"` (every pixel gets 16: the
/// supersampled reference the tests measure against).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(try_from = "Raw", into = "Raw")]
pub enum AntialiasOption {
    #[default]
    Off,
    /// 4 to 16 rays per edge pixel, by its contrast.
    Adaptive,
    Edges(u32),
    Reference,
}

/// What the scene file holds: a word, a number or a switch (anything else is refused by
/// [`AntialiasOption::parse`] with the accepted values).
#[derive(Deserialize, Serialize)]
#[serde(untagged)]
enum Raw {
    Samples(i64),
    Switch(bool),
    Word(String),
    Other(toml::Value),
}

impl TryFrom<Raw> for AntialiasOption {
    type Error = String;
    fn try_from(r: Raw) -> Result<Self, String> {
        match r {
            Raw::Samples(n) => AntialiasOption::parse(&n.to_string()),
            Raw::Other(v) => AntialiasOption::parse(&v.to_string()),
            Raw::Switch(b) => AntialiasOption::parse(&b.to_string()),
            Raw::Word(w) => AntialiasOption::parse(&w),
        }
    }
}

impl From<AntialiasOption> for Raw {
    fn from(a: AntialiasOption) -> Raw {
        match a {
            AntialiasOption::Off => Raw::Word("off".into()),
            AntialiasOption::Adaptive => Raw::Word("edges".into()),
            AntialiasOption::Edges(n) => Raw::Samples(n.into()),
            AntialiasOption::Reference => Raw::Word("reference".into()),
        }
    }
}

impl AntialiasOption {
    /// `off`, `edges`, `reference`, `4`, `8` or `16` (the CLI's `--antialias` too).
    pub fn parse(s: &str) -> Result<AntialiasOption, String> {
        match s.trim() {
            "off" | "false" => Ok(AntialiasOption::Off),
            "edges" | "on" | "true" => Ok(AntialiasOption::Adaptive),
            "reference" => Ok(AntialiasOption::Reference),
            "4" => Ok(AntialiasOption::Edges(4)),
            "8" => Ok(AntialiasOption::Edges(8)),
            "16" => Ok(AntialiasOption::Edges(16)),
            x => Err(format!(
                "`{x}` is not off, edges, reference or a sample count 4, 8 or 16"
            )),
        }
    }

    /// Sub-pixel rays per anti-aliased pixel, the most when adaptive (0: off).
    pub fn samples(self) -> u32 {
        match self {
            AntialiasOption::Off => 0,
            AntialiasOption::Edges(n) => n,
            AntialiasOption::Adaptive | AntialiasOption::Reference => 16,
        }
    }

    /// Each edge pixel's count chosen from its contrast (`"edges"`).
    pub fn adaptive(self) -> bool {
        self == AntialiasOption::Adaptive
    }

    /// Every pixel gets the samples (the reference), not only edge pixels.
    pub fn every_pixel(self) -> bool {
        self == AntialiasOption::Reference
    }
}

#[cfg(test)]
mod tests {
    use super::AntialiasOption;

    #[derive(serde::Deserialize)]
    struct R {
        antialias: AntialiasOption,
    }

    fn parse(v: &str) -> Result<AntialiasOption, String> {
        toml::from_str::<R>(&format!("antialias = {v}"))
            .map(|r| r.antialias)
            .map_err(|e| e.to_string())
    }

    #[test]
    fn words_and_counts() {
        assert_eq!(parse("\"off\""), Ok(AntialiasOption::Off));
        assert_eq!(parse("\"edges\""), Ok(AntialiasOption::Adaptive));
        assert_eq!(parse("16"), Ok(AntialiasOption::Edges(16)));
        assert_eq!(parse("8"), Ok(AntialiasOption::Edges(8)));
        assert_eq!(parse("\"reference\""), Ok(AntialiasOption::Reference));
        assert_eq!(parse("true"), Ok(AntialiasOption::Adaptive));
        assert_eq!(parse("false"), Ok(AntialiasOption::Off));
        for bad in ["5", "0", "-4", "\"smooth\"", "1e9", "8.5", "[4]"] {
            let e = parse(bad).unwrap_err();
            assert!(e.contains("4, 8 or 16"), "{bad}: {e}");
        }
    }
}
