// hapticdesk board: four load cells (full bridges) read by one ADS1256 on an ESP32, 1,000
// samples a second, one line per sample in hapticdesk's serial line format (docs/serial.md).
//
// NOT COMPILED OR RUN BY HAPTICDESK'S TESTS: the tests feed the same format to the source
// through a pseudo-terminal. Build it with the Arduino IDE or arduino-cli (board: ESP32 Dev
// Module) and check the hello and a few lines in a serial monitor before `hapticdesk run`.
//
// The ADS1256 has one converter behind a multiplexer: the four bridges are read one after
// the other, each as soon as the previous conversion is out (its datasheet's "cycling
// through the inputs": 4,374 readings a second at 30 kSPS, ~229 µs apart). A sample starts
// every 1,000 µs; the stamp is the sample's number (`stamp=seq`), counted from the board's
// clock so that a late sample skips a number rather than shifting the ones after it. When
// each bridge is read within its sample is measured at start and said in the hello
// (`offsets_us=`); hapticdesk aligns the four readings to the sample's time.
//
// Wiring (a Waveshare-style ADS1256 module: 7.68 MHz crystal, AVDD 5 V, 2.5 V reference):
//   module DVDD -> ESP32 3V3, AVDD -> 5 V, both GNDs -> GND
//   SCLK -> GPIO18, DIN -> GPIO23 (MOSI), DOUT -> GPIO19 (MISO), CS -> GPIO5,
//   DRDY -> GPIO4, RESET -> GPIO16, PDWN -> 3V3
//   bridges, differential: front-left fl AIN0(+)/AIN1(-), front-right fr AIN2/AIN3,
//   back-left bl AIN4/AIN5, back-right br AIN6/AIN7; every bridge's E+ to 5 V (AVDD) and E-
//   to GND. At 1 mV/V a cell gives 5 mV at full load: gain 64 (±39 mV) keeps it in range.
// The channel names are the desk profile's raw channels, in its order.

#include <SPI.h>

const int PIN_CS = 5, PIN_DRDY = 4, PIN_RESET = 16;
const char *const CHANNELS = "fl_fz,fr_fz,bl_fz,br_fz";
const uint8_t MUX[4] = {0x01, 0x23, 0x45, 0x67};  // AINp << 4 | AINn for each bridge
const uint32_t PERIOD_US = 1000;                  // 1 kHz: sample_rate_hz: 1000
const unsigned long BAUD = 921600;               // ~45 bytes a line: 450 kbit/s

// ADS1256 commands and registers (datasheet tables 23 and 24)
const uint8_t CMD_WAKEUP = 0x00, CMD_RDATA = 0x01, CMD_SDATAC = 0x0F, CMD_WREG = 0x50,
              CMD_SYNC = 0xFC, CMD_RESET = 0xFE;
const uint8_t REG_STATUS = 0x00, REG_MUX = 0x01, REG_ADCON = 0x02, REG_DRATE = 0x03;
const uint8_t DRATE_30K = 0xF0, ADCON_GAIN_64 = 0x06;

SPISettings ads(1900000, MSBFIRST, SPI_MODE1);  // SCLK at most fCLKIN / 4
uint32_t offsetsUs[4];                          // when each bridge is read in its sample
uint32_t start;                                 // micros() of sample 0
uint32_t seq;

void sendLine(const char *text) {  // text, `*`, the XOR of its bytes as two hex digits
  uint8_t x = 0;
  for (const char *p = text; *p; ++p) x ^= (uint8_t)*p;
  char tail[6];
  snprintf(tail, sizeof tail, "*%02X\n", x);
  Serial.print(text);
  Serial.print(tail);
}

void sendHello() {
  char text[200];
  snprintf(text, sizeof text,
           "@hapticdesk/1 rate=%lu channels=%s offsets_us=%lu,%lu,%lu,%lu checksum=xor "
           "board=ads1256-esp32",
           (unsigned long)(1000000UL / PERIOD_US), CHANNELS, (unsigned long)offsetsUs[0],
           (unsigned long)offsetsUs[1], (unsigned long)offsetsUs[2], (unsigned long)offsetsUs[3]);
  sendLine(text);
}

void command(uint8_t c) {
  digitalWrite(PIN_CS, LOW);
  SPI.transfer(c);
  digitalWrite(PIN_CS, HIGH);
}

void writeRegister(uint8_t reg, uint8_t value) {
  digitalWrite(PIN_CS, LOW);
  SPI.transfer(CMD_WREG | reg);
  SPI.transfer(0x00);  // one register
  SPI.transfer(value);
  digitalWrite(PIN_CS, HIGH);
}

void waitReady() {
  while (digitalRead(PIN_DRDY) == HIGH) {
  }
}

// One step of the datasheet's input cycling: point the multiplexer at `next`, restart the
// conversion (SYNC, WAKEUP), and read the conversion of the bridge selected before.
long cycle(uint8_t next) {
  digitalWrite(PIN_CS, LOW);
  SPI.transfer(CMD_WREG | REG_MUX);
  SPI.transfer(0x00);
  SPI.transfer(next);
  SPI.transfer(CMD_SYNC);
  delayMicroseconds(4);  // t11: 24 × 1/fCLKIN
  SPI.transfer(CMD_WAKEUP);
  SPI.transfer(CMD_RDATA);
  delayMicroseconds(7);  // t6: 50 × 1/fCLKIN before the data
  uint32_t v = (uint32_t)SPI.transfer(0) << 16;
  v |= (uint32_t)SPI.transfer(0) << 8;
  v |= SPI.transfer(0);
  digitalWrite(PIN_CS, HIGH);
  if (v & 0x800000UL) v |= 0xFF000000UL;
  return (long)v;
}

// Read the four bridges of one sample; `at` gets each reading's micros(). The multiplexer
// is on bridge 0 already (the last step of the sample before): its conversion restarts now,
// so none of the four is older than the sample.
void readSample(long value[4], uint32_t at[4]) {
  command(CMD_SYNC);
  delayMicroseconds(4);
  command(CMD_WAKEUP);
  for (uint8_t i = 0; i < 4; ++i) {
    waitReady();  // the conversion of bridge i is done
    at[i] = micros();
    value[i] = cycle(MUX[(i + 1) % 4]);  // and bridge i + 1's has begun
  }
}

void setup() {
  Serial.begin(BAUD);
  pinMode(PIN_CS, OUTPUT);
  digitalWrite(PIN_CS, HIGH);
  pinMode(PIN_DRDY, INPUT);
  pinMode(PIN_RESET, OUTPUT);
  digitalWrite(PIN_RESET, LOW);
  delay(1);
  digitalWrite(PIN_RESET, HIGH);
  delay(50);
  SPI.begin();
  SPI.beginTransaction(ads);
  command(CMD_SDATAC);  // no continuous read: every result asked for with RDATA
  writeRegister(REG_STATUS, 0x06);  // auto-calibration on, input buffer on
  writeRegister(REG_ADCON, ADCON_GAIN_64);
  writeRegister(REG_DRATE, DRATE_30K);
  writeRegister(REG_MUX, MUX[0]);
  command(CMD_SYNC);
  command(CMD_WAKEUP);
  // measure when each bridge is read after a sample's start: the mean of 200 samples
  uint64_t sum[4] = {0, 0, 0, 0};
  long value[4];
  uint32_t at[4];
  for (int n = 0; n < 200; ++n) {
    uint32_t t0 = micros();
    readSample(value, at);
    for (uint8_t i = 0; i < 4; ++i) sum[i] += at[i] - t0;
  }
  for (uint8_t i = 0; i < 4; ++i) offsetsUs[i] = (uint32_t)(sum[i] / 200);
  sendHello();  // after every reset: hapticdesk then knows the board restarted
  start = micros();
  seq = 0;
}

void loop() {
  while (Serial.available()) {  // the host asks `?` when it opens the port
    if (Serial.read() == '?') sendHello();
  }
  // the sample's number follows the clock: a sample started late (the line took long to
  // go out) skips numbers, and hapticdesk counts those samples lost
  uint32_t due = start + seq * PERIOD_US;
  while ((int32_t)(micros() - due) < 0) {
  }
  seq = (micros() - start) / PERIOD_US;
  long value[4];
  uint32_t at[4];
  readSample(value, at);
  char text[96];
  snprintf(text, sizeof text, "%lu,%ld,%ld,%ld,%ld", (unsigned long)seq, value[0], value[1],
           value[2], value[3]);
  sendLine(text);
  ++seq;
}
