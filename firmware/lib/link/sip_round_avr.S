#if defined(__AVR__)   // first: another assembler (PlatformIO's native env) would read the ';' comments as code
; One SipRound on the ATmega328P: void rovernav_sip_round(uint8_t v[32]), v0..v3 little-endian.
;
; avr-gcc's 64-bit arithmetic goes through memory and library shift loops: a C++ round on uint64_t
; siphash.cpp costs about 1,280 cycles here. Written for the AVR, the round is 4 sub-steps,
; each on two of the four 64-bit words held in 16 registers (a0-a7 = r18-r25, b0-b7 = r0, r1,
; r27, r13-r17: as many call-clobbered ones as the pointer Z and the loop count r26 leave, so
; that only five need saving; r1, the compiler's zero, is cleared again before the return).
; A rotation by a multiple of 8 bits moves no data: the code names the bytes in their rotated
; order (the macros' argument lists); only the odd bits (13 = 16 - 3, 21 = 24 - 3, 17 = 16 + 1)
; cost single-bit rotations, 10 cycles each (the two runs of three in a loop: 34 bytes less
; each, for 3 cycles a turn). Measured with
; python benchmarks/bench_mac.py; checked against the reference vectors on the image by
; tests/test_siphash.py (test_siphash_on_the_avr_image).
;
; The round (v little-endian in memory, v0 at v+0 ... v3 at v+24):
;   v0 += v1; v1 = rotl(v1, 13) ^ v0; v0 = rotl(v0, 32)
;   v2 += v3; v3 = rotl(v3, 16) ^ v2
;   v0 += v3; v3 = rotl(v3, 21) ^ v0
;   v2 += v1; v1 = rotl(v1, 17) ^ v2; v2 = rotl(v2, 32)
; Only compiled for the AVR; elsewhere siphash.cpp's C++ round is used.

.macro LOAD8 off, r0, r1, r2, r3, r4, r5, r6, r7
  ldd \r0, Z+\off
  ldd \r1, Z+\off+1
  ldd \r2, Z+\off+2
  ldd \r3, Z+\off+3
  ldd \r4, Z+\off+4
  ldd \r5, Z+\off+5
  ldd \r6, Z+\off+6
  ldd \r7, Z+\off+7
.endm

.macro STORE8 off, r0, r1, r2, r3, r4, r5, r6, r7
  std Z+\off, \r0
  std Z+\off+1, \r1
  std Z+\off+2, \r2
  std Z+\off+3, \r3
  std Z+\off+4, \r4
  std Z+\off+5, \r5
  std Z+\off+6, \r6
  std Z+\off+7, \r7
.endm

; a += b, byte 0 first (the lists name each word's bytes from least to most significant)
.macro ADD8 a0, a1, a2, a3, a4, a5, a6, a7, b0, b1, b2, b3, b4, b5, b6, b7
  add \a0, \b0
  adc \a1, \b1
  adc \a2, \b2
  adc \a3, \b3
  adc \a4, \b4
  adc \a5, \b5
  adc \a6, \b6
  adc \a7, \b7
.endm

; w ^= a
.macro XOR8 w0, w1, w2, w3, w4, w5, w6, w7, a0, a1, a2, a3, a4, a5, a6, a7
  eor \w0, \a0
  eor \w1, \a1
  eor \w2, \a2
  eor \w3, \a3
  eor \w4, \a4
  eor \w5, \a5
  eor \w6, \a6
  eor \w7, \a7
.endm

; w = rotr(w, 3): three turns of a one-bit rotation, bit 0 going round to bit 63 through T
.macro ROR64X3 w0, w1, w2, w3, w4, w5, w6, w7
  ldi r26, 3
1:
  bst \w0, 0
  lsr \w7
  ror \w6
  ror \w5
  ror \w4
  ror \w3
  ror \w2
  ror \w1
  ror \w0
  bld \w7, 7
  dec r26
  brne 1b
.endm

; w = rotl(w, 1): bit 63 goes round to bit 0 through T
.macro ROL64 w0, w1, w2, w3, w4, w5, w6, w7
  bst \w7, 7
  lsl \w0
  rol \w1
  rol \w2
  rol \w3
  rol \w4
  rol \w5
  rol \w6
  rol \w7
  bld \w0, 0
.endm

; Words as register lists. B rotated left by 16 bits is B16 (its byte i is b[i-2]), and so on.
#define A   r18, r19, r20, r21, r22, r23, r24, r25
#define A32 r22, r23, r24, r25, r18, r19, r20, r21
#define B   r0, r1, r27, r13, r14, r15, r16, r17
#define B16 r16, r17, r0, r1, r27, r13, r14, r15
#define B40 r13, r14, r15, r16, r17, r0, r1, r27

.section .text.rovernav_sip_round,"ax",@progbits
.global rovernav_sip_round
.type rovernav_sip_round, @function
rovernav_sip_round:
  push r13
  push r14
  push r15
  push r16
  push r17
  movw r30, r24            ; Z = v

  ; v0 += v1; v1 = rotl(v1, 13) ^ v0; v0 = rotl(v0, 32)
  LOAD8 0, A
  LOAD8 8, B
  ADD8 A, B
  ROR64X3 B16              ; rotl 13 = rotl 16, then rotr 3
  XOR8 B16, A
  STORE8 8, B16
  STORE8 0, A32

  ; v2 += v3; v3 = rotl(v3, 16) ^ v2 (v3 stays in the B registers, as B16)
  LOAD8 16, A
  LOAD8 24, B
  ADD8 A, B
  XOR8 B16, A
  STORE8 16, A

  ; v0 += v3; v3 = rotl(v3, 21) ^ v0 (v3 rotated 24 more bits is B40)
  LOAD8 0, A
  ADD8 A, B16
  ROR64X3 B40              ; rotl 21 = rotl 24, then rotr 3
  XOR8 B40, A
  STORE8 24, B40
  STORE8 0, A

  ; v2 += v1; v1 = rotl(v1, 17) ^ v2; v2 = rotl(v2, 32)
  LOAD8 16, A
  LOAD8 8, B
  ADD8 A, B
  ROL64 B16                ; rotl 17 = rotl 16, then rotl 1
  XOR8 B16, A
  STORE8 8, B16
  STORE8 16, A32

  pop r17
  pop r16
  pop r15
  pop r14
  pop r13
  clr r1                   ; the compiler's zero register, used as b1 above
  ret
.size rovernav_sip_round, .-rovernav_sip_round

#endif
