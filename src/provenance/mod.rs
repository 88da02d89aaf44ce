//! Which code built a result: the crate's import graph ([`imports`]) and the source hashes
//! compiled into the binary ([`sources`]). The results lock (`pipeline::store`) records,
//! for each kept stage, the hashes of the files its kind is built from, so a result made by
//! code that has changed since is reported as such, whatever its cache key says (the key
//! hashes no code; kind versions are bumped by hand).
pub mod imports;
pub mod sources;
