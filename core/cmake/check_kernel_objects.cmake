# Run by `cmake -P` after bsplab_core is built: every symbol a kernel object
# file defines for the linker must be in its own level's namespace
# (bsp::isa_<level>::). An inline function compiled with, say, AVX2 flags and
# left out of line would be a weak symbol the linker may pick for the
# baseline code too, which would then crash on a CPU without AVX2.
# Arguments: -DNM=<nm> -DOBJECTS=<a;b;c>
foreach(obj IN LISTS OBJECTS)
  execute_process(COMMAND ${NM} -C --defined-only ${obj}
                  OUTPUT_VARIABLE out RESULT_VARIABLE rc)
  if (NOT rc EQUAL 0)
    message(FATAL_ERROR "nm failed on ${obj}")
  endif()
  string(REPLACE "\n" ";" lines "${out}")
  foreach(line IN LISTS lines)
    # "<address> <type> <name>": global (upper-case type) or unique (u) symbols.
    if (line MATCHES "^[0-9a-f]+ ([A-Zu]) (.*)$")
      set(type "${CMAKE_MATCH_1}")
      set(name "${CMAKE_MATCH_2}")
      # DW.ref.__gxx_personality_v0: the unwinder's pointer to the C++
      # personality routine (data, no instructions), which builds with
      # exceptions in their unwind tables (the sanitizer builds) emit.
      if (NOT name MATCHES "^bsp::isa_[a-z0-9]+::" AND NOT name STREQUAL "DW.ref.__gxx_personality_v0")
        message(FATAL_ERROR "kernel object ${obj} exports ${name} (type ${type}): "
                "an out-of-line copy compiled for one instruction set, which the linker "
                "could use on a CPU without it. Inline it (the entries are `flatten`) or "
                "give it internal linkage.")
      endif()
    endif()
  endforeach()
endforeach()
