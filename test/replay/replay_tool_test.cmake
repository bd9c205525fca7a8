# gmm_mcl_replay end to end: --make-fixture writes the synthetic scene as a TUM folder with its
# map, then the tool replays it (one trial) and must succeed and write its outputs.
file(REMOVE_RECURSE ${WORK})
execute_process(COMMAND ${TOOL} --make-fixture tum ${WORK}/tum --frames 90 --width 160 --seed 2
                RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "--make-fixture failed (${rc})")
endif()
execute_process(COMMAND ${TOOL} --format tum --dataset ${WORK}/tum --map ${WORK}/tum/map.gmm
                        --trials 1 --num-particles 300 --init-half-extent 0.5
                        --init-yaw-half-range 0.3 --hold-frames 15 --tail-frames 30
                        --out ${WORK}/out --quiet
                RESULT_VARIABLE rc OUTPUT_VARIABLE out)
message("${out}")
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "replay of the TUM fixture did not succeed (${rc})")
endif()
foreach(f summary.md summary.csv trial_1_estimate.tum trial_1_truth.tum trial_1.csv)
  if(NOT EXISTS ${WORK}/out/${f})
    message(FATAL_ERROR "missing output ${f}")
  endif()
endforeach()
file(STRINGS ${WORK}/out/trial_1_estimate.tum lines)
list(LENGTH lines n)
if(NOT n EQUAL 90)
  message(FATAL_ERROR "trial_1_estimate.tum has ${n} poses, expected 90")
endif()

# The same with the odometry withheld (the constant-velocity model predicts) at 15 Hz (every
# second frame): it must still succeed, write one pose per replayed frame and say what it did
# (docs/no_odometry.md).
execute_process(COMMAND ${TOOL} --format tum --dataset ${WORK}/tum --map ${WORK}/tum/map.gmm
                        --trials 1 --num-particles 300 --init-half-extent 0.5
                        --init-yaw-half-range 0.3 --hold-frames 8 --tail-frames 15
                        --odometry none --frame-step 2 --out ${WORK}/out_no_odometry --quiet
                RESULT_VARIABLE rc OUTPUT_VARIABLE out)
message("${out}")
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "replay of the TUM fixture without odometry did not succeed (${rc})")
endif()
if(NOT out MATCHES "odometry withheld, attitude from the truth, every 2. frame")
  message(FATAL_ERROR "the replay does not say that the odometry was withheld")
endif()
file(STRINGS ${WORK}/out_no_odometry/trial_1_estimate.tum lines)
list(LENGTH lines n)
if(NOT n EQUAL 45)
  message(FATAL_ERROR "trial_1_estimate.tum has ${n} poses without odometry, expected 45")
endif()
execute_process(COMMAND ${TOOL} --format tum --dataset ${WORK}/tum --map ${WORK}/tum/map.gmm
                        --odometry sometimes RESULT_VARIABLE rc ERROR_VARIABLE err)
if(rc EQUAL 0 OR NOT err MATCHES "--odometry: truth or none")
  message(FATAL_ERROR "--odometry sometimes was not refused (${rc}): ${err}")
endif()
