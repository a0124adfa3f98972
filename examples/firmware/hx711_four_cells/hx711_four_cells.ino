// hapticdesk board: four load cells under a desk's top, each on its own HX711, one line per
// sample in hapticdesk's serial line format (docs/serial.md).
//
// NOT COMPILED OR RUN BY HAPTICDESK'S TESTS: the tests feed the same format to the source
// through a pseudo-terminal. Build it with the Arduino IDE or arduino-cli for your board and
// check the hello and a few lines in a serial monitor before `hapticdesk run`.
//
// Each HX711 converts on its own clock (80 samples/s, a few % apart from chip to chip), so
// each chip is read the moment it is ready, and each line says when: the stamp is the
// board's micros() at the earliest of the four readings, then the four readings, then each
// reading's time after the stamp in µs (`offsets=line`); hapticdesk aligns them to the
// stamp before it adds up the legs. A line is printed once all four chips have a new reading.
//
// Wiring (Arduino Uno or Nano at 5 V; an ESP32 works too, at 3.3 V, with other pins):
//   HX711 #1, front-left leg  (fl): DOUT -> D2, PD_SCK -> D3
//   HX711 #2, front-right leg (fr): DOUT -> D4, PD_SCK -> D5
//   HX711 #3, back-left leg   (bl): DOUT -> D6, PD_SCK -> D7
//   HX711 #4, back-right leg  (br): DOUT -> D8, PD_SCK -> D9
//   every HX711 module: VCC -> 5 V, GND -> GND, RATE -> VCC (80 samples/s; GND gives 10/s:
//   then also set RATE_HZ = 10 here and sample_rate_hz: 10 in the profile)
//   each cell's four wires to its module: E+ red, E- black, A- white, A+ green (the usual
//   colours; check your cell's sheet). Bathroom-scale half-bridge cells go in pairs.
// The channel names are the desk profile's raw channels, in its order (<sensor>_fz for a
// `kind: load_cell` sensor): hapticdesk refuses a board whose hello names others.

const uint8_t DOUT_PIN[4] = {2, 4, 6, 8};
const uint8_t SCK_PIN[4] = {3, 5, 7, 9};
const char *const CHANNELS = "fl_fz,fr_fz,bl_fz,br_fz";
const unsigned RATE_HZ = 80;
const unsigned long BAUD = 250000;  // exact on a 16 MHz AVR; 115200 is enough at 80 Hz

long reading[4];
unsigned long readAt[4];  // micros() when each chip's reading was ready
bool fresh[4];

// Print `text` with its NMEA-style checksum: `*` and the XOR of every byte, two hex digits.
void sendLine(const char *text) {
  uint8_t x = 0;
  for (const char *p = text; *p; ++p) x ^= (uint8_t)*p;
  char tail[6];
  snprintf(tail, sizeof tail, "*%02X\n", x);
  Serial.print(text);
  Serial.print(tail);
}

void sendHello() {
  char text[160];
  snprintf(text, sizeof text,
           "@hapticdesk/1 rate=%u channels=%s stamp=us offsets=line checksum=xor board=hx711x4",
           RATE_HZ, CHANNELS);
  sendLine(text);
}

// Shift one conversion out of chip i (24 bits, MSB first) and a 25th pulse: channel A at
// gain 128 for the next one. PD_SCK high for more than 60 µs would power the chip down, so
// interrupts wait the ~50 µs this takes.
long readChip(uint8_t i) {
  uint32_t v = 0;
  noInterrupts();
  for (uint8_t b = 0; b < 24; ++b) {
    digitalWrite(SCK_PIN[i], HIGH);
    delayMicroseconds(1);
    v = (v << 1) | (uint32_t)digitalRead(DOUT_PIN[i]);
    digitalWrite(SCK_PIN[i], LOW);
    delayMicroseconds(1);
  }
  digitalWrite(SCK_PIN[i], HIGH);
  delayMicroseconds(1);
  digitalWrite(SCK_PIN[i], LOW);
  interrupts();
  if (v & 0x800000UL) v |= 0xFF000000UL;  // two's complement, 24 bits to 32
  return (long)v;
}

void setup() {
  Serial.begin(BAUD);
  for (uint8_t i = 0; i < 4; ++i) {
    pinMode(DOUT_PIN[i], INPUT);
    pinMode(SCK_PIN[i], OUTPUT);
    digitalWrite(SCK_PIN[i], LOW);
  }
  sendHello();  // after every reset: hapticdesk then knows the board restarted
}

void loop() {
  while (Serial.available()) {  // the host asks `?` when it opens the port
    if (Serial.read() == '?') sendHello();
  }
  for (uint8_t i = 0; i < 4; ++i) {
    if (digitalRead(DOUT_PIN[i]) == LOW) {  // this chip's conversion is ready
      readAt[i] = micros();
      reading[i] = readChip(i);  // a chip twice ready before the others: its newer reading
      fresh[i] = true;
    }
  }
  if (!(fresh[0] && fresh[1] && fresh[2] && fresh[3])) return;
  unsigned long stamp = readAt[0];
  for (uint8_t i = 1; i < 4; ++i) {
    if ((long)(readAt[i] - stamp) < 0) stamp = readAt[i];  // the earliest (micros() wraps)
  }
  char text[120];
  snprintf(text, sizeof text, "%lu,%ld,%ld,%ld,%ld,%lu,%lu,%lu,%lu", stamp, reading[0],
           reading[1], reading[2], reading[3], readAt[0] - stamp, readAt[1] - stamp,
           readAt[2] - stamp, readAt[3] - stamp);
  sendLine(text);
  for (uint8_t i = 0; i < 4; ++i) fresh[i] = false;
}
