#!/usr/bin/env bash
# Open a report written by `ergohand validate` (report.html, or the suite's index.html) in
# headless Chromium and fail if any image is missing or broken, as a reader's browser would
# show it: every <img> must have loaded (complete, with a natural size) from a copy of the page
# alone in an empty folder with the network shut off, so a picture that is not embedded in the
# page cannot load either.
#
#   bash validation/tools/check_report.sh REPORT.html [MORE.html ...]
#
# Installs Chromium with apt-get when it is not there (CI calls this on a clean machine).
# Exit status: 0 all images load; 1 a broken/missing image or no image at all; 2 usage or
# set-up error.
set -euo pipefail

if [ "$#" -lt 1 ]; then
  echo "usage: $0 REPORT.html [MORE.html ...]" >&2
  exit 2
fi

CHECK_NAME=check_report
# shellcheck source=chromium.sh
. "$(cd "$(dirname "$0")" && pwd)/chromium.sh"
need_chromium

status=0
for report in "$@"; do
  if [ ! -f "$report" ]; then
    echo "check_report: $report: no such file" >&2
    status=1
    continue
  fi
  work=$(mktemp -d)
  # A copy of the page alone in a fresh folder (the report must be self-contained, so a
  # picture referenced by file name fails here) with a probe appended: after the load event
  # it lists every image that did not load. The original is not modified.
  probe="$work/page.html"
  trap 'rm -rf "$work"' EXIT
  cat "$report" > "$probe"
  cat >> "$probe" <<'EOF'
<script>
window.addEventListener("load", function () {
  var imgs = Array.prototype.slice.call(document.images);
  var bad = imgs.filter(function (i) {
    return !(i.complete && i.naturalWidth > 0 && i.naturalHeight > 0);
  }).map(function (i) {
    return (i.alt || "(no alt)") + " <- " + (i.getAttribute("src") || "(no src)").slice(0, 60);
  });
  var out = document.createElement("pre");
  out.id = "check-report-result";
  // The markers are split so that the script's own text in the dumped DOM never matches.
  var m = "CHECK-" + "REPORT";
  out.textContent = m + " images=" + imgs.length + " broken=" + bad.length + "\n" + bad.join("\n") + "\nEND-" + m;
  document.body.appendChild(out);
});
</script>
EOF
  dom="$work/dom.html"
  if ! timeout 120 "$CHROMIUM" --headless --no-sandbox --disable-gpu \
      --disable-background-networking --disable-component-update --disable-sync \
      --no-first-run --user-data-dir="$work/profile" \
      --host-resolver-rules="MAP * ~NOTFOUND" \
      --virtual-time-budget=20000 --dump-dom "file://$probe" > "$dom" 2> "$work/stderr"; then
    echo "check_report: $report: chromium failed:" >&2
    tail -5 "$work/stderr" >&2
    status=2
    rm -rf "$work"
    continue
  fi
  result=$(sed -n '/CHECK-REPORT images=/,/END-CHECK-REPORT/p' "$dom")
  rm -rf "$work"
  if [ -z "$result" ]; then
    echo "check_report: $report: the page did not finish loading in Chromium" >&2
    status=1
    continue
  fi
  images=$(echo "$result" | head -1 | sed 's/.*images=\([0-9]*\).*/\1/')
  broken=$(echo "$result" | head -1 | sed 's/.*broken=\([0-9]*\).*/\1/')
  if [ "$images" = 0 ]; then
    echo "check_report: $report: no image at all" >&2
    status=1
  elif [ "$broken" != 0 ]; then
    echo "check_report: $report: $broken of $images images missing or broken:" >&2
    echo "$result" | sed '1d;$d' | sed 's/^/  /' >&2
    status=1
  else
    echo "check_report: $report: all $images images load"
  fi
done
exit $status
