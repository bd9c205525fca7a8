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
