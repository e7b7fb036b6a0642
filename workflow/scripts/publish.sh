#!/usr/bin/env bash
# One scene's step after its chunk (rule fit_chunk): move the scene's new files of this step
# from the chunk's staging folder into place (a rename: atomic), keep a file the chunk did not
# redo (up to date), or fail with the scene's error line (on standard error and in the log).
#   publish.sh STEP WHAT STAGED LOG SCENE OUTPUT...
# STEP: fit, truth or plots (the chunk's error file is STAGED/STEP.error); WHAT: what failed,
# in words. After the fit's file, its fingerprint (what it was made from) goes beside the
# scene's log: the chunk skips the scene while it matches.
set -u
step=$1 what=$2 staged=$3 log=$4 scene=$5
shift 5
: >"$log"
if [[ -e $staged/$step.error ]]; then
    echo "dashpot: scene $scene: $what failed: $(cat "$staged/$step.error")" | tee -a "$log" >&2
    exit 1
fi
for output in "$@"; do
    name=$(basename "$output")
    if [[ -e $staged/$name ]]; then
        mkdir -p "$(dirname "$output")" && mv -f "$staged/$name" "$output" || exit 1
        echo "wrote $output" >>"$log"
    elif [[ -e $output ]]; then
        echo "kept $output (up to date)" >>"$log"
    else
        echo "dashpot: scene $scene: $output was not made (see its log in results/logs)" |
            tee -a "$log" >&2
        exit 1
    fi
done
if [[ $step == fit && -e $staged/fingerprint.json ]]; then
    mkdir -p results/logs/fit && mv -f "$staged/fingerprint.json" "results/logs/fit/$scene.fingerprint"
fi
exit 0
