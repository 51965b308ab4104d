# Shared by the docs/precision.md table scripts (sourced): the vizsim binary (first argument,
# default target/release/vizsim), a temporary folder removed on exit, and the datasets of the
# tables (the real datasets and five 64³ phantoms).
vizsim=${1:-target/release/vizsim}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
datasets="fuel neghip aneurism engine bonsai boston_teapot hydrogen_atom tooth_103x94x161 tooth_140x120x161 foot-lossy"
for kind in sphere shells jet metaballs cast; do datasets="$datasets phantom:$kind:64"; done
