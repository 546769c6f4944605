#!/usr/bin/env bash
# docs_check.sh - the repository's docs stand alone:
#  - README.md has at most 250 lines;
#  - no file names a path outside the repository (the shared notes' directory), the design
#    notes' file, or an issue by its number (the word and a number or the letter N, or a hash
#    sign and a number);
#  - every relative link and image of every README.md points to an existing file, and a link's
#    #anchor to a heading of its target;
#  - every `file.c:function` pointer of a README.md names a function (an identifier) that the
#    file holds, the file taken relative to the README or to the project.
# The files are those git tracks when PROJECT_DIR is a git checkout, else every file under it
# (build and output directories left out). The patterns are built from pieces, so this file
# does not match them itself.
# usage: bash docs_check.sh PROJECT_DIR
set -u
cd "${1:?usage: docs_check.sh PROJECT_DIR}" || exit 2
fails=0
fail() { echo "docs_check: FAIL: $*" >&2; fails=$((fails + 1)); }

if [ -e .git ] && command -v git > /dev/null && git ls-files > /dev/null 2>&1; then
  mapfile -t files < <(git ls-files)
else
  mapfile -t files < <(find . -type f ! -path './.git/*' ! -path './build*' ! -path './out/*' \
                         ! -path './scratch/*' | sed 's|^\./||' | sort)
fi
[ ${#files[@]} -gt 0 ] || { echo "docs_check: no files found" >&2; exit 1; }

# 1. README.md at most 250 lines
lines=$(wc -l < README.md)
[ "$lines" -le 250 ] || fail "README.md has $lines lines (at most 250)"

# 2. nothing outside the repository, no design notes, no issue numbers
outside='\.\./sha''red'
design='DESI''GN\.md'
issue='(^|[^a-z0-9_])iss''ues? ?#?([0-9]+|n)([^a-z0-9_]|$)'
hash_number='(^|[^a-z0-9_&#])#[0-9]+'
for pat in "$outside" "$design" "$issue" "$hash_number"; do
  hits=$(printf '%s\0' "${files[@]}" | xargs -0 grep -n -I -i -E -- "$pat" 2>/dev/null)
  [ -z "$hits" ] || fail "pattern $pat:"$'\n'"$hits"
done

# 3, 4. links and file:function pointers of every README.md
readmes=()
for f in "${files[@]}"; do
  case "$f" in README.md | */README.md) readmes+=("$f") ;; esac
done
out=$(python3 - "${readmes[@]}" <<'EOF'
import os, re, sys

def strip_code(text):
    text = re.sub(r'^```.*?^```', '', text, flags=re.S | re.M)
    return text

def slug(heading):
    s = heading.strip().lower()
    s = re.sub(r'[^\w\- ]', '', s)
    return s.replace(' ', '-')

def anchors(path):
    with open(path, encoding='utf-8') as f:
        text = strip_code(f.read())
    return {slug(m.group(1)) for m in re.finditer(r'^#{1,6}\s+(.*?)\s*#*\s*$', text, re.M)}

bad = 0
for readme in sys.argv[1:]:
    base = os.path.dirname(readme)
    with open(readme, encoding='utf-8') as f:
        raw = f.read()
    text = strip_code(raw)
    # links and images outside code spans
    prose = re.sub(r'`[^`\n]*`', '', text)
    for m in re.finditer(r'\[[^\]\n]*\]\(\s*<?([^)\s>]+)>?(?:\s+"[^"]*")?\s*\)', prose):
        target = m.group(1)
        if re.match(r'^[a-z][a-z0-9+.-]*:', target, re.I):
            continue  # http:, https:, mailto:
        path, _, anchor = target.partition('#')
        full = os.path.normpath(os.path.join(base, path)) if path else readme
        if not os.path.exists(full):
            print(f'{readme}: link to a missing file: {target}')
            bad += 1
            continue
        if anchor and full.endswith('.md') and anchor not in anchors(full):
            print(f'{readme}: link to a missing heading: {target}')
            bad += 1
    # `file.c:function` pointers (in code spans and in tables)
    for m in re.finditer(r'`((?:\.\./|[\w.-]+/)*[\w.-]+\.(?:c|h|cpp|sh|py)):([A-Za-z_]\w*)`', raw):
        rel, name = m.group(1), m.group(2)
        cands = [os.path.normpath(os.path.join(base, rel)), os.path.normpath(rel)]
        src = next((c for c in cands if os.path.isfile(c)), None)
        if src is None:
            print(f'{readme}: `{rel}:{name}`: no such file')
            bad += 1
            continue
        with open(src, encoding='utf-8', errors='replace') as f:
            code = f.read()
        if not re.search(r'\b' + re.escape(name) + r'\b', code):
            print(f'{readme}: `{rel}:{name}`: {src} has no {name}')
            bad += 1
sys.exit(1 if bad else 0)
EOF
) || fail "READMEs:"$'\n'"$out"

if [ "$fails" -eq 0 ]; then
  echo "docs_check: ok (README.md $lines lines, ${#files[@]} files, ${#readmes[@]} READMEs)"
fi
[ "$fails" -eq 0 ]
