# gmm_mcl_replay end to end: --make-fixture writes the synthetic scene as a TUM folder with its
# map, then the tool replays it (one trial) and must succeed and write its outputs.

# replay_fixture(OUT_DIR WHAT POSES ARGS...): replays the fixture (one trial, 300 particles, a
# small start region) with ARGS into ${WORK}/OUT_DIR; it must succeed and write POSES poses.
# WHAT names the case in the failures; the tool's output is left in `out`.
function(replay_fixture out_dir what poses)
  execute_process(COMMAND ${TOOL} --format tum --dataset ${WORK}/tum --map ${WORK}/tum/map.gmm
                          --trials 1 --num-particles 300 --init-half-extent 0.5
                          --init-yaw-half-range 0.3 ${ARGN} --out ${WORK}/${out_dir} --quiet
                  RESULT_VARIABLE rc OUTPUT_VARIABLE out)
  message("${out}")
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "replay of the TUM fixture${what} did not succeed (${rc})")
  endif()
  file(STRINGS ${WORK}/${out_dir}/trial_1_estimate.tum lines)
  list(LENGTH lines n)
  if(NOT n EQUAL poses)
    message(FATAL_ERROR "trial_1_estimate.tum has ${n} poses${what}, expected ${poses}")
  endif()
  set(out "${out}" PARENT_SCOPE)
endfunction()

file(REMOVE_RECURSE ${WORK})
execute_process(COMMAND ${TOOL} --make-fixture tum ${WORK}/tum --frames 90 --width 160 --seed 2
                RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "--make-fixture failed (${rc})")
endif()
replay_fixture(out "" 90 --hold-frames 15 --tail-frames 30)
foreach(f summary.md summary.csv trial_1_estimate.tum trial_1_truth.tum trial_1.csv)
  if(NOT EXISTS ${WORK}/out/${f})
    message(FATAL_ERROR "missing output ${f}")
  endif()
endforeach()
# The per-frame file: the spread columns last, one row per frame, each as many fields as the
# header.
file(STRINGS ${WORK}/out/trial_1.csv rows)
list(GET rows 0 header)
if(NOT header MATCHES ",position_sigma_m,yaw_sigma_rad$")
  message(FATAL_ERROR "trial_1.csv: no spread columns at the end of its header: ${header}")
endif()
string(REGEX REPLACE "[^,]" "" header_commas "${header}")
list(LENGTH rows row_count)
if(NOT row_count EQUAL 91)
  message(FATAL_ERROR "trial_1.csv: ${row_count} lines, expected a header and 90 frames")
endif()
list(GET rows 90 last_row)
string(REGEX REPLACE "[^,]" "" last_commas "${last_row}")
if(NOT last_commas STREQUAL header_commas)
  message(FATAL_ERROR "trial_1.csv: the last frame's fields do not match the header's")
endif()

# The same with the odometry withheld (the constant-velocity model predicts) at 15 Hz (every
# second frame): it must still succeed, write one pose per replayed frame and say what it did
# (docs/no_odometry.md).
replay_fixture(out_no_odometry " without odometry" 45
               --hold-frames 8 --tail-frames 15 --odometry none --frame-step 2)
if(NOT out MATCHES "odometry withheld, attitude from the truth, every 2. frame")
  message(FATAL_ERROR "the replay does not say that the odometry was withheld")
endif()
execute_process(COMMAND ${TOOL} --format tum --dataset ${WORK}/tum --map ${WORK}/tum/map.gmm
                        --odometry sometimes RESULT_VARIABLE rc ERROR_VARIABLE err)
if(rc EQUAL 0 OR NOT err MATCHES "--odometry: truth or none")
  message(FATAL_ERROR "--odometry sometimes was not refused (${rc}): ${err}")
endif()
