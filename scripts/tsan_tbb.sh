#!/usr/bin/env bash
# Builds oneTBB with ThreadSanitizer into PREFIX (default build-tsan/onetbb) for the tsan stage of
# scripts/test.sh: Debian's libtbb.so is not instrumented, so TSan does not see its scheduler's
# synchronisation and every TBB task of ours would look racy (README "ThreadSanitizer and TBB").
#
# The source is Debian's own source package of the installed libtbb-dev, same version (apt-get
# source, through a private source list and package lists in PREFIX: the system's apt
# configuration is not changed; apt checks the download against the archive's signed index).
# Only libtbb is built (no tbbmalloc, tbbbind, tests or examples). Idempotent: a finished build
# of the same version is reused.
#
# Prints the directory to pass as TBB_DIR (PREFIX/install/lib/cmake/TBB) on its last line.
set -euo pipefail
cd "$(dirname "$0")/.."
prefix="$(mkdir -p "${1:-build-tsan/onetbb}" && cd "${1:-build-tsan/onetbb}" && pwd)"
jobs="${NURBSREG_JOBS:-$(nproc)}"

version="$(dpkg-query -W -f='${Version}' libtbb-dev)"
tbb_dir="$prefix/install/lib/cmake/TBB"
stamp="$prefix/install/.nurbsreg-built-from"
if [ -f "$stamp" ] && [ "$(cat "$stamp")" = "onetbb $version" ] && [ -f "$tbb_dir/TBBConfig.cmake" ]; then
  echo "tsan_tbb: oneTBB $version with ThreadSanitizer already in $prefix/install" >&2
  echo "$tbb_dir"
  exit 0
fi

sudo=""
[ "$(id -u)" -ne 0 ] && sudo="sudo"
apt_dir="$prefix/apt"
rm -rf "$apt_dir" "$prefix/src" "$prefix/build" "$prefix/install"
mkdir -p "$apt_dir/lists/partial" "$prefix/src"
# The binary sources' URIs and suites (deb822 or one-line), as deb-src lines.
sources=""
for f in /etc/apt/sources.list /etc/apt/sources.list.d/*.sources /etc/apt/sources.list.d/*.list; do
  [ -f "$f" ] || continue
  sources+="$(cat "$f")"$'\n'
done
{
  echo "$sources" | awk '
    /^Types:/ { deb = ($0 ~ /[[:space:]]deb([[:space:]]|$)/) }
    /^URIs:/ { uri = $2 }
    /^Suites:/ { suites = ""; for (i = 2; i <= NF; ++i) suites = suites " " $i }
    /^Components:/ { comps = ""; for (i = 2; i <= NF; ++i) comps = comps " " $i }
    /^Signed-By:/ { key = $2 }
    /^$/ { if (deb && uri != "" && uri ~ /debian/) { n = split(suites, s, " ");
             for (i = 1; i <= n; ++i) printf "deb-src [signed-by=%s] %s %s%s\n", key, uri, s[i], comps }
           deb = 0; uri = ""; suites = ""; comps = ""; key = "" }
    END { if (deb && uri != "" && uri ~ /debian/) { n = split(suites, s, " ");
             for (i = 1; i <= n; ++i) printf "deb-src [signed-by=%s] %s %s%s\n", key, uri, s[i], comps } }'
  echo "$sources" | grep -E '^deb[[:space:]]' | grep debian | sed 's/^deb[[:space:]]/deb-src /' || true
} | sort -u >"$apt_dir/sources.list"
if [ ! -s "$apt_dir/sources.list" ]; then
  echo "tsan_tbb: no Debian source found in /etc/apt to fetch the onetbb source package from" >&2
  exit 1
fi
apt_opts=(-o "Dir::Etc::SourceList=$apt_dir/sources.list" -o "Dir::Etc::SourceParts=/dev/null"
  -o "Dir::State::Lists=$apt_dir/lists" -o "APT::Sandbox::User=root")
echo "tsan_tbb: fetching the onetbb $version source package" >&2
$sudo apt-get "${apt_opts[@]}" update -q >&2
(cd "$prefix/src" && $sudo apt-get "${apt_opts[@]}" source --download-only -q "onetbb=$version" >&2)
$sudo chown -R "$(id -u):$(id -g)" "$prefix/src" "$apt_dir"
orig="$(ls "$prefix"/src/onetbb_*.orig.tar.* | head -1)"
tar -xf "$orig" -C "$prefix/src"
source_dir="$(find "$prefix/src" -mindepth 1 -maxdepth 1 -type d -name 'oneTBB*' | head -1)"

echo "tsan_tbb: building oneTBB $version with -fsanitize=thread" >&2
launcher=()
command -v ccache >/dev/null 2>&1 && launcher=(-DCMAKE_C_COMPILER_LAUNCHER=ccache -DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
CC=clang CXX=clang++ cmake -S "$source_dir" -B "$prefix/build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O2 -gline-tables-only" -DTBB_SANITIZE=thread \
  -DTBB_TEST=OFF -DTBB_EXAMPLES=OFF -DTBBMALLOC_BUILD=OFF -DTBB_DISABLE_HWLOC_AUTOMATIC_SEARCH=ON \
  -DTBB_STRICT=OFF -DCMAKE_INSTALL_PREFIX="$prefix/install" "${launcher[@]}" >&2
cmake --build "$prefix/build" --parallel "$jobs" >&2
cmake --install "$prefix/build" >&2
echo "onetbb $version" >"$stamp"
echo "$tbb_dir"
