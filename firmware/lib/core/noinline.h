// ROVERNAV_NOINLINE keeps a function out of line in the Uno image. There, LTO at -Os pastes a
// function into its callers whenever it judges that smaller, but it counts a float operation as
// one instruction where the AVR spends a library call and a dozen register moves, and the huge
// function it grows has more locals than the AVR's short stack offsets reach. Each use is
// measured with tools/build_uno.py and saves flash; on the host it only costs a call.
#pragma once

#define ROVERNAV_NOINLINE __attribute__((noinline))
