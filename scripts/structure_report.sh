#!/usr/bin/env bash
# The workspace's structure in numbers (issue 42): which heavy libraries each package's shared libraries and binaries
# load (ldd, so transitive ones count), lines of C++ per package and per source folder, and the largest functions.
# Run it before and after a restructuring and compare.
#   scripts/structure_report.sh [--build DIR] [--top N]
set -u  # no -e: grep and find that match nothing are normal here
cd "$(dirname "$0")/.."
build=build
top=15
while [ $# -gt 0 ]; do
  case "$1" in
    --build) build="$2"; shift 2 ;;
    --top) top="$2"; shift 2 ;;
    -h|--help) sed -n 2,5p "$0"; exit 0 ;;
    *) echo "structure_report.sh: unknown argument '$1'" >&2; exit 2 ;;
  esac
done

heavy='lib(fcl|assimp|OSMesa|GL|rosbag|rosbag_storage|roscpp|BulletSoftBody|Qt5Widgets|pq|sqlite3)\.so'
echo "## Heavy libraries loaded (ldd of $build/devel/lib)"
echo
echo "| package | file | loads |"
echo "|---|---|---|"
for package_dir in src/*/; do
  package=$(basename "$package_dir")
  [ -f "$package_dir/package.xml" ] || continue
  {
    ls "$build"/devel/lib/lib*.so 2>/dev/null | while read -r library; do
      # A library belongs to the package whose CMakeLists.txt names its target.
      target=$(basename "$library" .so); target=${target#lib}
      if grep -qE "add_library\(\s*$target[ )]" "$package_dir/CMakeLists.txt"; then echo "$library"; fi
    done
    find "$build/devel/lib/$package" -maxdepth 1 -type f -perm -u+x 2>/dev/null | grep -v '\.py$' | sort
  } | while read -r file; do
    if ! file -b "$file" | grep -q ELF; then continue; fi
    loads=$(ldd "$file" 2>/dev/null | { grep -oE "$heavy" || true; } | sed 's/\.so$//' | sort -u | tr '\n' ' ')
    echo "| $package | $(basename "$file") | ${loads:--} |"
  done
done

echo
echo "## Lines of C++ (.h/.cpp, tests and fuzz targets included) per package and source folder"
echo
echo "| package | folder | lines |"
echo "|---|---|---|"
for package_dir in src/*/; do
  package=$(basename "$package_dir")
  total=$(find "$package_dir" -name '*.cpp' -o -name '*.h' | xargs -r cat | wc -l)
  echo "| $package | (all) | $total |"
  find "$package_dir" \( -name '*.cpp' -o -name '*.h' \) -printf '%h\n' | sort | uniq | while read -r folder; do
    lines=$(find "$folder" -maxdepth 1 \( -name '*.cpp' -o -name '*.h' \) | xargs -r cat | wc -l)
    echo "| $package | ${folder#$package_dir} | $lines |"
  done
done

echo
echo "## The $top largest functions (Universal Ctags line:..end:)"
echo
echo "| lines | function | file |"
echo "|---|---|---|"
find src -name '*.cpp' -not -path '*/test/*' -print0 |
  xargs -0 ctags --fields=+ne --c++-kinds=f -o - 2>/dev/null |
  awk -F'\t' '{ line = ""; end = ""; scope = "";
                for (i = 4; i <= NF; ++i) {
                  if ($i ~ /^line:/) line = substr($i, 6);
                  if ($i ~ /^end:/) end = substr($i, 5);
                  if ($i ~ /^(class|struct|namespace|function):/) scope = substr($i, index($i, ":") + 1);
                }
                if (line != "" && end != "" && $1 !~ /^__anon/)
                  printf "%d\t%s%s\t%s:%s\n", end - line + 1, (scope == "" ? "" : scope "::"), $1, $2, line }' |
  sort -rn | head -n "$top" | awk -F'\t' '{ printf "| %s | %s | %s |\n", $1, $2, $3 }'
